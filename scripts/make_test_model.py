"""Write tiny ONNX models in the FastSAM / YOLOv8-seg output format, with known outputs,
for segloc's tests of the ONNX segmenter (no pretrained weights are needed or used).

tiny_yoloseg.onnx: input "images" [1, 3, 160, 160]; outputs
  output0 [1, 4 + 1 + 32, 4]  (boxes cx, cy, w, h in input pixels; 1 class score; 32 coefficients)
  output1 [1, 32, 40, 40]     (prototype masks at 1/4 resolution)
The outputs do not depend on the image (it only enters as 0 * mean(image)):
  prototype 0: +4 inside the disk centred at input (60, 80), radius 15 px; -4 elsewhere
  prototype 1: +4 inside the square input x 100..128, y 60..88 (whole 4-px cells); -4 elsewhere
  candidate 0: box around the disk, score 0.9, coefficients e0        -> kept
  candidate 1: nearly the same box, score 0.8, e0                     -> removed by NMS
  candidate 2: box around the square, score 0.85, e1                  -> kept
  candidate 3: score 0.1                                              -> below threshold
For a 1280 x 720 image (scale 0.125, vertical padding 35) the disk maps to the image disk
centred at (480, 360) with radius 120 px, the square to x 800..1024, y 200..424.

tiny_bad_outputs.onnx: the same input, a single output: the ONNX segmenter must refuse it.

usage: python3 scripts/make_test_model.py OUT_DIR
"""
import os
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

S, P, K, N = 160, 40, 32, 4


def prototypes():
    protos = np.full((1, K, P, P), -4.0, dtype=np.float32)
    ys, xs = np.mgrid[0:P, 0:P]
    # prototype pixel centres in input pixels
    cx, cy = (xs + 0.5) * S / P, (ys + 0.5) * S / P
    protos[0, 0][(cx - 60) ** 2 + (cy - 80) ** 2 <= 15 ** 2] = 4.0
    protos[0, 1][(cx >= 100) & (cx < 128) & (cy >= 60) & (cy < 88)] = 4.0
    return protos


def predictions():
    preds = np.zeros((1, 4 + 1 + K, N), dtype=np.float32)
    rows = [
        # cx, cy, w, h, score, coefficient index
        (60, 80, 34, 34, 0.90, 0),
        (61, 80, 34, 34, 0.80, 0),
        (115, 75, 34, 34, 0.85, 1),
        (20, 20, 10, 10, 0.10, 1),
    ]
    for i, (cx, cy, w, h, score, k) in enumerate(rows):
        preds[0, 0:4, i] = (cx, cy, w, h)
        preds[0, 4, i] = score
        preds[0, 5 + k, i] = 1.0
    return preds


def constant_plus_zero_input(name, value, nodes, inits):
    """output = value + 0 * mean(images): a graph that consumes its input."""
    inits.append(numpy_helper.from_array(value, name + "_value"))
    nodes.append(helper.make_node("Add", [name + "_value", "zero"], [name]))


def model(good):
    nodes, inits = [], []
    nodes.append(helper.make_node("ReduceMean", ["images"], ["mean"], keepdims=0))
    inits.append(numpy_helper.from_array(np.array(0.0, dtype=np.float32), "zero_factor"))
    nodes.append(helper.make_node("Mul", ["mean", "zero_factor"], ["zero"]))
    constant_plus_zero_input("output0", predictions(), nodes, inits)
    outputs = [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 4 + 1 + K, N])]
    if good:
        constant_plus_zero_input("output1", prototypes(), nodes, inits)
        outputs.append(helper.make_tensor_value_info("output1", TensorProto.FLOAT, [1, K, P, P]))
    graph = helper.make_graph(
        nodes,
        "tiny_yoloseg" if good else "tiny_bad_outputs",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, S, S])],
        outputs,
        initializer=inits,
    )
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    m.ir_version = 8
    onnx.checker.check_model(m)
    return m


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "target/test-models"
    os.makedirs(out, exist_ok=True)
    onnx.save(model(True), os.path.join(out, "tiny_yoloseg.onnx"))
    onnx.save(model(False), os.path.join(out, "tiny_bad_outputs.onnx"))
    print(os.path.join(out, "tiny_yoloseg.onnx"))


if __name__ == "__main__":
    main()
