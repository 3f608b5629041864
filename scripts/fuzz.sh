#!/usr/bin/env bash
# Coverage-guided fuzzing of one of dronewatt's readers with cargo fuzz (libFuzzer).
#
#   scripts/fuzz.sh TARGET [SECONDS]     TARGET: decoder | tlog | raw | csv | config | plan | dataflash | ulog | trees
#   scripts/fuzz.sh all [SECONDS]        each target in turn
#
# Works on the stable toolchain (RUSTC_BOOTSTRAP=1 lets cargo fuzz use -Z flags). Builds
# without a sanitizer (-s none): the readers are safe Rust, so AddressSanitizer would find
# nothing the bounds checks do not, at several times the cost; the targets' property checks
# (src/fuzz_props/) and debug assertions do the catching. libFuzzer works on a scratch
# copy of the committed seeds (fuzz/corpus/TARGET, git-ignored); a crash lands in
# fuzz/artifacts/TARGET/. Copy it to fuzz/regressions/TARGET/ once fixed, and
# `cargo test --test it fuzz_props::` replays it for ever after.
#
# FUZZ_RUNS=N stops a target after N executions (whichever comes first with SECONDS):
#   FUZZ_RUNS=10000000 scripts/fuzz.sh decoder 1800
set -euo pipefail
cd "$(dirname "$0")/.."

targets=(decoder tlog raw csv config plan dataflash ulog trees)
target=${1:-}
seconds=${2:-60}
if [[ -z "$target" ]]; then
  echo "usage: $0 TARGET|all [SECONDS]   (targets: ${targets[*]})" >&2
  exit 2
fi
if [[ "$target" == all ]]; then
  for t in "${targets[@]}"; do "$0" "$t" "$seconds"; done
  exit 0
fi
if [[ ! " ${targets[*]} " == *" $target "* ]]; then
  echo "$0: unknown target '$target' (targets: ${targets[*]})" >&2
  exit 2
fi

if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "installing cargo-fuzz (once)…" >&2
  cargo install cargo-fuzz --locked
fi

# The dronewatt crate does not link libtorch (that is dronewatt-torch), so neither do
# the fuzz binaries.
export RUSTC_BOOTSTRAP=1

corpus=fuzz/corpus/$target
mkdir -p "$corpus" fuzz/artifacts/"$target"
cp -n fuzz/seeds/"$target"/* "$corpus"/ 2>/dev/null || true
cd fuzz
nice -n 10 cargo fuzz run -s none "$target" "corpus/$target" -- \
  -max_total_time="$seconds" ${FUZZ_RUNS:+-runs=$FUZZ_RUNS} -max_len=4096 -rss_limit_mb=2048 -print_final_stats=1
