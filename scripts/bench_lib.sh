# Shared by the bench scripts (sourced from the repository root, after `cd`):
#   source scripts/bench_lib.sh
#   segloc_bin [--example NAME ...]   sets $target and $bin: $SEGLOC_BIN when set (nothing is
#                                     built), else `cargo build --release` of the segloc binary
#                                     (and the examples named) and $target/release/segloc.
#   need_data DIR NAME                fails with a message naming the script when
#                                     $data/DIR is missing; $data is $SEGLOC_DATA or ../shared/data.

data="${SEGLOC_DATA:-../shared/data}"
target="${CARGO_TARGET_DIR:-target}"

segloc_bin() {
  if [[ -n "${SEGLOC_BIN:-}" ]]; then
    bin="$SEGLOC_BIN"
  else
    nice -n 10 cargo build --release --quiet --bin segloc "$@"
    bin="$target/release/segloc"
  fi
}

need_data() {
  [[ -e "$data/$1" ]] || { echo "$2: no $1 under $data (set SEGLOC_DATA)" >&2; exit 1; }
}
