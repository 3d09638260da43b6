#!/usr/bin/env python3
"""Train segloc's learned boulder segmenter on rendered frames and export it to ONNX.

The model is a compact U-Net that reads the left image at half resolution (1 × 360 × 640,
grey levels / 255) and writes three logits per pixel at quarter resolution (3 × 180 × 320):
background, rock, rock boundary (rock pixels that touch another rock instance). segloc
decodes them into instances by connected components of the rock class after the boundary
class has cut touching rocks apart (src/perception/unet_decoder.rs).

Data: directories written by `segloc sim render --half` (left PNG + 16-bit instance ids).
Nothing of the real LAC pairs is read: they are the test.

usage:
  python scripts/train_segmenter.py --train DIR [DIR ...] --val DIR [DIR ...] \
      --out models/boulders.onnx [--minutes 30] [--seed 0] [--log runs/train.log]
"""

import argparse
import json
import math
import pathlib
import random
import time

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from PIL import Image

IN_H, IN_W = 360, 640  # model input (half of the IPEX 1280 × 720)
OUT_STRIDE = 2  # output pixels per input pixel side: logits at 180 × 320
LANDER = 65535
CROP = 192  # training crops of the half-resolution image (input pixels)


# ---------------------------------------------------------------- data


def boundary_of(ids):
    """Rock pixels with a 4- or 8-neighbour of another rock instance."""
    h, w = ids.shape
    pad = np.pad(ids, 1, mode="edge")
    out = np.zeros((h, w), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy == 0 and dx == 0:
                continue
            nb = pad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
            out |= (nb != ids) & (nb > 0) & (ids > 0)
    return out


def labels_at_output(ids_half):
    """Class map at the output resolution from half-resolution instance ids.

    A 2 × 2 block is rock when any of its pixels is rock (its id: the block's most
    frequent rock id), so that small far rocks survive the downsampling."""
    ids = ids_half.astype(np.int64)
    ids[ids == LANDER] = 0
    h, w = ids.shape[0] // OUT_STRIDE, ids.shape[1] // OUT_STRIDE
    blocks = ids[: h * OUT_STRIDE, : w * OUT_STRIDE].reshape(h, OUT_STRIDE, w, OUT_STRIDE)
    blocks = blocks.transpose(0, 2, 1, 3).reshape(h, w, OUT_STRIDE * OUT_STRIDE)
    out_ids = blocks.max(axis=2)  # any rock pixel: one of its ids (the largest)
    classes = (out_ids > 0).astype(np.int64)
    classes[boundary_of(out_ids)] = 2
    return classes, out_ids


def load_dirs(dirs):
    """Left images (uint8, H × W) and output-resolution class maps of every frame."""
    images, targets, names = [], [], []
    for d in dirs:
        d = pathlib.Path(d)
        for left in sorted(d.glob("*_0.png")):
            ids_path = left.with_name(left.name.replace("_0.png", "_ids.png"))
            if not ids_path.exists():
                continue
            img = np.asarray(Image.open(left).convert("L"))
            ids = np.asarray(Image.open(ids_path)).astype(np.int64)
            if img.shape != (IN_H, IN_W):
                raise SystemExit(f"{left}: {img.shape}, expected {(IN_H, IN_W)} (render with --half)")
            classes, _ = labels_at_output(ids)
            images.append(img)
            targets.append(classes)
            names.append(str(left))
    if not images:
        raise SystemExit(f"no frames found in {dirs}")
    return np.stack(images), np.stack(targets), names


def augment(img, rng):
    """Photometric augmentations for the domain gap: exposure, gamma, blur, grain, noise."""
    x = img.astype(np.float32) / 255.0
    x = np.clip(x * rng.uniform(0.55, 1.6), 0, 1)  # exposure
    x = x ** rng.uniform(0.7, 1.45)  # gamma
    if rng.random() < 0.5:  # blur: separable 3-tap kernel of random strength
        a = rng.uniform(0.05, 0.3)
        k = np.array([a, 1 - 2 * a, a], np.float32)
        x = np.apply_along_axis(lambda r: np.convolve(r, k, mode="same"), 1, x)
        x = np.apply_along_axis(lambda c: np.convolve(c, k, mode="same"), 0, x)
    if rng.random() < 0.5:  # ground texture: a multiplicative log-normal field of random grain
        x = x * grain_field(x.shape, rng)
    x = x + rng.normal(0, rng.uniform(0, 0.025), x.shape).astype(np.float32)  # noise
    return np.clip(x, 0, 1).astype(np.float32)


def grain_field(shape, rng):
    """exp(σ·n) with n a unit Gaussian field on a coarse grid of 3–16 px cells, bilinearly
    upsampled, σ ≤ 0.2: the real ground's grainier albedo texture than the renderer's."""
    h, w = shape
    cell = rng.uniform(3, 16)
    gh, gw = int(h / cell) + 2, int(w / cell) + 2
    coarse = rng.normal(0, 1, (gh, gw)).astype(np.float32)
    up = np.asarray(Image.fromarray(coarse, mode="F").resize((int(gw * cell), int(gh * cell)), Image.BILINEAR))
    return np.exp(rng.uniform(0, 0.2) * up[:h, :w]).astype(np.float32)


def batch(images, targets, n, rng):
    """n random crops (flipped half of the time), augmented."""
    xs, ys = [], []
    oc = CROP // OUT_STRIDE
    for _ in range(n):
        i = rng.integers(len(images))
        # bias the crop towards the lower part of the image, where the ground is
        oy = rng.integers(0, (IN_H - CROP) // OUT_STRIDE + 1)
        ox = rng.integers(0, (IN_W - CROP) // OUT_STRIDE + 1)
        img = images[i, oy * OUT_STRIDE : oy * OUT_STRIDE + CROP, ox * OUT_STRIDE : ox * OUT_STRIDE + CROP]
        tgt = targets[i, oy : oy + oc, ox : ox + oc]
        if rng.random() < 0.5:
            img, tgt = img[:, ::-1], tgt[:, ::-1]
        xs.append(augment(img, rng))
        ys.append(np.ascontiguousarray(tgt))
    return torch.from_numpy(np.stack(xs)[:, None]), torch.from_numpy(np.stack(ys))


# ---------------------------------------------------------------- model


def conv(cin, cout, k=3, stride=1):
    return nn.Sequential(
        nn.Conv2d(cin, cout, k, stride=stride, padding=k // 2, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class UNet(nn.Module):
    """Input 1 × H × W, output 3 × H/2 × W/2 (H, W multiples of 16).

    Sized for 2 CPU cores (about 0.3 GMAC on 360 × 640): a stride-2 stem, three pooled
    encoder levels, and a decoder that adds (rather than concatenates) each skip after a
    1 × 1 projection, with one 3 × 3 convolution per level."""

    def __init__(self, ch=(8, 16, 32, 64)):
        super().__init__()
        c0, c1, c2, c3 = ch
        self.stem = conv(1, c0, stride=2)
        self.e0 = conv(c0, c0)
        self.e1 = nn.Sequential(conv(c0, c1), conv(c1, c1))
        self.e2 = nn.Sequential(conv(c1, c2), conv(c2, c2))
        self.e3 = nn.Sequential(conv(c2, c3), conv(c3, c3))
        self.p2, self.d2 = conv(c3, c2, k=1), conv(c2, c2)
        self.p1, self.d1 = conv(c2, c1, k=1), conv(c1, c1)
        self.p0, self.d0 = conv(c1, c0, k=1), conv(c0, c0)
        self.head = nn.Conv2d(c0, 3, 1)

    @staticmethod
    def up(x, like):
        return F.interpolate(x, size=like.shape[-2:], mode="nearest")

    def forward(self, x):
        x0 = self.e0(self.stem(x))
        x1 = self.e1(F.max_pool2d(x0, 2))
        x2 = self.e2(F.max_pool2d(x1, 2))
        x3 = self.e3(F.max_pool2d(x2, 2))
        y2 = self.d2(self.up(self.p2(x3), x2) + x2)
        y1 = self.d1(self.up(self.p1(y2), x1) + x1)
        y0 = self.d0(self.up(self.p0(y1), x0) + x0)
        return self.head(y0)


# ---------------------------------------------------------------- validation


def components(mask):
    """4-connected components of a boolean map: list of pixel-index arrays."""
    h, w = mask.shape
    label = np.zeros((h, w), np.int32)
    comps = []
    for y0, x0 in zip(*np.nonzero(mask)):
        if label[y0, x0]:
            continue
        n = len(comps) + 1
        stack, pix = [(y0, x0)], []
        label[y0, x0] = n
        while stack:
            y, x = stack.pop()
            pix.append((y, x))
            for yy, xx in ((y + 1, x), (y - 1, x), (y, x + 1), (y, x - 1)):
                if 0 <= yy < h and 0 <= xx < w and mask[yy, xx] and not label[yy, xx]:
                    label[yy, xx] = n
                    stack.append((yy, xx))
        comps.append(np.array(pix))
    return comps, label


@torch.no_grad()
def validate(model, images, targets):
    """Loss, rock IoU and instance recall / precision (instances of ≥ 4 output pixels)."""
    model.eval()
    loss, inter, union, tp, fn, fp = 0.0, 0, 0, 0, 0, 0
    for i in range(len(images)):
        x = torch.from_numpy(images[i : i + 1, None].astype(np.float32) / 255.0)
        y = torch.from_numpy(targets[i : i + 1])
        logits = model(x)
        loss += F.cross_entropy(logits, y, weight=CLASS_WEIGHTS).item()
        pred = logits.argmax(1)[0].numpy()
        truth = targets[i]
        inter += int(((pred == 1) & (truth >= 1)).sum())
        union += int(((pred >= 1) | (truth >= 1)).sum())
        pcomps, plabel = components(pred == 1)
        tcomps, tlabel = components(truth == 1)
        hit_pred = set()
        for c in tcomps:
            if len(c) < 4:
                continue
            hits = plabel[c[:, 0], c[:, 1]]
            hits = hits[hits > 0]
            if len(hits):
                tp += 1
                hit_pred.update(np.unique(hits).tolist())
            else:
                fn += 1
        for k, c in enumerate(pcomps, start=1):
            if len(c) >= 4 and k not in hit_pred and not (truth[c[:, 0], c[:, 1]] >= 1).any():
                fp += 1
    model.train()
    n = len(images)
    return {
        "val_loss": loss / n,
        "rock_iou": inter / max(union, 1),
        "instance_recall": tp / max(tp + fn, 1),
        "instance_precision": (tp) / max(tp + fp, 1),
    }


# ---------------------------------------------------------------- main

CLASS_WEIGHTS = torch.tensor([1.0, 4.0, 8.0])


def export(model, path):
    model.eval()
    dummy = torch.zeros(1, 1, IN_H, IN_W)
    torch.onnx.export(
        model,
        dummy,
        str(path),
        input_names=["image"],
        output_names=["logits"],
        opset_version=17,
        dynamo=False,
    )
    model.train()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--train", nargs="+", required=True)
    ap.add_argument("--val", nargs="+", required=True)
    ap.add_argument("--out", default="models/boulders.onnx")
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--batch", type=int, default=12)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--log", default=None, help="JSON lines of the loss and validation figures")
    args = ap.parse_args()

    torch.manual_seed(args.seed)
    random.seed(args.seed)
    rng = np.random.default_rng(args.seed)
    torch.set_num_threads(args.threads)

    train_x, train_y, train_names = load_dirs(args.train)
    val_x, val_y, _ = load_dirs(args.val)
    frac = [(train_y == k).mean() for k in range(3)]
    print(f"train frames {len(train_x)}, val frames {len(val_x)}, class fractions {frac}", flush=True)

    model = UNet()
    params = sum(p.numel() for p in model.parameters())
    print(f"parameters: {params}", flush=True)
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=1e-4)
    log = open(args.log, "w") if args.log else None
    start = time.time()
    budget = args.minutes * 60
    step, running, best = 0, 0.0, None
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    while time.time() - start < budget:
        lr = args.lr * 0.5 * (1 + math.cos(math.pi * min(1.0, (time.time() - start) / budget)))
        for g in opt.param_groups:
            g["lr"] = lr
        x, y = batch(train_x, train_y, args.batch, rng)
        loss = F.cross_entropy(model(x), y, weight=CLASS_WEIGHTS)
        opt.zero_grad()
        loss.backward()
        opt.step()
        running = 0.98 * running + 0.02 * loss.item() if step else loss.item()
        step += 1
        if step % 100 == 0:
            rec = {"step": step, "minutes": (time.time() - start) / 60, "lr": lr, "train_loss": running}
            if step % 500 == 0:
                rec.update(validate(model, val_x, val_y))
                score = rec["instance_recall"] + rec["instance_precision"]
                if best is None or score >= best:
                    best = score
                    export(model, out)
                    rec["exported"] = True
            print(json.dumps(rec), flush=True)
            if log:
                log.write(json.dumps(rec) + "\n")
                log.flush()
    rec = {"step": step, "minutes": (time.time() - start) / 60, "final": True}
    rec.update(validate(model, val_x, val_y))
    score = rec["instance_recall"] + rec["instance_precision"]
    if best is None or score >= best:
        export(model, out)
        rec["exported"] = True
    print(json.dumps(rec), flush=True)
    if log:
        log.write(json.dumps(rec) + "\n")
    print(f"parameters {params}, steps {step}, model {out} ({out.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
