#!/usr/bin/env bash
# Put the onnxruntime shared library where segloc looks for it (target/onnxruntime/),
# taken from the official `onnxruntime` wheel on PyPI: the `ort` crate's own download of
# prebuilt binaries is not used (segloc builds `ort` with `load-dynamic`).
#
# usage: scripts/fetch-onnxruntime.sh [DEST_DIR]
#   prints the library path; export it as ORT_DYLIB_PATH or leave it in target/onnxruntime/
#   where segloc finds it by itself.
# env:   ORT_VERSION (default 1.31.1; must match ort's `api-31` feature: >= 1.31),
#        ORT_WHEEL_PLATFORM (default: this machine's, e.g. manylinux_2_28_x86_64)
# needs: python3 with pip, network access to PyPI (once).
set -euo pipefail
cd "$(dirname "$0")/.."

version="${ORT_VERSION:-1.31.1}"
dest="${1:-target/onnxruntime}"
lib="$dest/libonnxruntime.so.$version"

if [[ -f "$lib" ]]; then
  echo "$(realpath "$lib")"
  exit 0
fi
case "$(uname -s)-$(uname -m)" in
  Linux-x86_64)  platform="${ORT_WHEEL_PLATFORM:-manylinux_2_28_x86_64}" ;;
  Linux-aarch64) platform="${ORT_WHEEL_PLATFORM:-manylinux_2_28_aarch64}" ;;
  *) echo "fetch-onnxruntime: no wheel platform known for $(uname -s)-$(uname -m); set ORT_WHEEL_PLATFORM" >&2; exit 1 ;;
esac
command -v python3 >/dev/null || { echo "fetch-onnxruntime: python3 is needed" >&2; exit 1; }

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
echo "fetch-onnxruntime: downloading the onnxruntime $version wheel ($platform) from PyPI" >&2
python3 -m pip download --quiet --no-deps --only-binary=:all: \
  --platform "$platform" --python-version 3.12 --implementation cp \
  --dest "$work" "onnxruntime==$version" >&2

mkdir -p "$dest"
python3 - "$work" "$dest" "$version" <<'PY'
import pathlib, sys, zipfile
work, dest, version = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]), sys.argv[3]
wheels = sorted(work.glob("onnxruntime-*.whl"))
if not wheels:
    sys.exit("fetch-onnxruntime: pip produced no wheel")
found = False
with zipfile.ZipFile(wheels[0]) as wheel:
    for member in wheel.namelist():
        name = pathlib.PurePosixPath(member).name
        if name.startswith("libonnxruntime") and ".so" in name:
            (dest / name).write_bytes(wheel.read(member))
            found = True
if not found:
    sys.exit("fetch-onnxruntime: the wheel holds no libonnxruntime.so")
PY
[[ -f "$lib" ]] || { echo "fetch-onnxruntime: $lib missing after extraction" >&2; exit 1; }
ln -sf "libonnxruntime.so.$version" "$dest/libonnxruntime.so"
echo "$(realpath "$lib")"
