#!/usr/bin/env bash
# Run every cargo-fuzz target for SECONDS seconds each (default 30) on one
# core, starting from (and adding to) the committed corpus in fuzz/corpus/.
# Needs cargo-fuzz (`cargo install --locked cargo-fuzz`) and a C++ compiler;
# works on stable rustc: no sanitizer (-s none), debug assertions on (-a).
#   fuzz/run.sh 30        # CI: a short run
#   fuzz/run.sh 3600      # the longer run of docs/reliability.md
# Exits non-zero (and leaves the crashing input in fuzz/artifacts/) on a
# crash, panic or failed invariant. Prints libFuzzer's final stats line.
set -euo pipefail
cd "$(dirname "$0")"
secs=${1:-30}
targets=${FUZZ_TARGETS:-$(cargo fuzz list)}
for t in $targets; do
  mkdir -p "corpus/$t"
  echo "== fuzz $t for ${secs}s"
  # replay the regression inputs of past findings first
  if [ -d "regressions/$t" ]; then cargo fuzz run "$t" -s none -a "regressions/$t" -- -runs=0 >/dev/null 2>&1 || { echo "regression input of $t fails"; exit 1; }; fi
  cargo fuzz run "$t" -s none -a "corpus/$t" -- -max_total_time="$secs" -max_len=4096 -timeout=20 -print_final_stats=1 2>&1 \
    | grep -E "^(stat::number_of_executed_units|stat::average_exec_per_sec|stat::new_units_added|#[0-9]+ +DONE)|panicked|ERROR|SUMMARY|Test unit written" || true
  # grep hides libFuzzer's exit status: check for artifacts instead
  if compgen -G "artifacts/$t/*" > /dev/null; then
    echo "fuzz target $t failed; inputs in fuzz/artifacts/$t/"; exit 1
  fi
done
