#!/usr/bin/env bash
# The Python bindings' tests: build the wheel with maturin in a virtual environment,
# install it there and run pytest on python/tests.
#
# The wheel is built in the workspace's target directory (CARGO_TARGET_DIR, else target/),
# so after `cargo test --workspace --release` only the bindings' own crate is compiled.
# Extra maturin arguments (e.g. `--features segloc/rerun`, to build the root crate with the
# features the test run used) go in MATURIN_ARGS. The tests find the data at SEGLOC_DATA and
# the CLI at target/release/segloc (or SEGLOC_BIN).
set -euo pipefail
cd "$(dirname "$0")/.."

target="${CARGO_TARGET_DIR:-$(pwd)/target}"
venv="$target/python-venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install -q -r python/requirements-dev.txt

started=$(date +%s)
rm -rf "$target/wheels"
# shellcheck disable=SC2086 # MATURIN_ARGS is a list of arguments
"$venv/bin/maturin" build --release --quiet -m python/Cargo.toml -o "$target/wheels" ${MATURIN_ARGS:-}
echo "wheel built in $(( $(date +%s) - started )) s: $(ls "$target"/wheels/*.whl)"
"$venv/bin/pip" install -q --force-reinstall --no-deps "$target"/wheels/segloc-*.whl

# from the repository root, so that `import segloc` finds the installed wheel, not python/segloc
"$venv/bin/pytest" -q -p no:cacheprovider python/tests
