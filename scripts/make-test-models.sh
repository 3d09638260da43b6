#!/usr/bin/env bash
# Build the tiny ONNX test models (scripts/make_test_model.py) into target/test-models/,
# using a Python virtual environment with the `onnx` package under target/onnx-venv/.
# usage: scripts/make-test-models.sh   (idempotent; prints the model path)
set -euo pipefail
cd "$(dirname "$0")/.."
out="target/test-models"
if [[ -f "$out/tiny_yoloseg.onnx" && -f "$out/tiny_bad_outputs.onnx" && "$out/tiny_yoloseg.onnx" -nt scripts/make_test_model.py ]]; then
  echo "$out/tiny_yoloseg.onnx"; exit 0
fi
venv="target/onnx-venv"
if [[ ! -x "$venv/bin/python" ]]; then
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --upgrade pip >&2
fi
"$venv/bin/python" -c "import onnx" 2>/dev/null || "$venv/bin/python" -m pip install --quiet "onnx>=1.16,<2" >&2
"$venv/bin/python" scripts/make_test_model.py "$out"
