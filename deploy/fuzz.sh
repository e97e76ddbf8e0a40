#!/usr/bin/env bash
# Builds the libFuzzer harnesses (frictiond_add_fuzzer in
# cmake/FrictiondHelpers.cmake; docs/fuzzing.md) with clang into their own
# build directory and runs each for a bounded time from its committed seed
# corpus. Fails on any crash, leak, timeout or out-of-memory; prints the
# executions per harness. Run by deploy/test.sh after the tests.
#
# Environment:
#   FRICTIOND_FUZZ_SECONDS  seconds per harness (default 30)
#   FRICTIOND_FUZZ_JOBS     harnesses run at once (default 2)
#   FRICTIOND_FUZZ_DIR      build directory (default build-fuzz)
#   FRICTIOND_FUZZ_ONLY     regex: run only matching harnesses
# Findings (crash-*, leak-*, timeout-*, oom-*) are written to
# <build dir>/artifacts/<harness>/; reproduce with
#   <build dir>/fuzz/<harness> <artifact>
# then add the input as a regression test to the unit tests.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${FRICTIOND_FUZZ_SECONDS:-30}
jobs=${FRICTIOND_FUZZ_JOBS:-2}
dir=${FRICTIOND_FUZZ_DIR:-build-fuzz}
only=${FRICTIOND_FUZZ_ONLY:-.}

echo "== fuzz: building the harnesses (clang, $dir)"
# -O1 with line tables: quick to build, symbolized stacks on a finding.
CC=${FRICTIOND_FUZZ_CC:-clang} CXX=${FRICTIOND_FUZZ_CXX:-clang++} \
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFRICTIOND_BUILD_FUZZERS=ON \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -gline-tables-only" \
  "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -gline-tables-only" \
  -DFRICTIOND_BUILD_TESTS=OFF -DFRICTIOND_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build "$dir" -j"${FRICTIOND_JOBS:-2}" --target frictiond_fuzzers

run_one() {
  # name binary seed-corpus: runs one harness; its new inputs go to a
  # scratch corpus (the committed seeds are never modified).
  local name=$1 bin=$2 seeds=$3
  local work="$dir/corpus/$name" art="$dir/artifacts/$name" log="$dir/logs/$name.log"
  mkdir -p "$work" "$art" "$(dirname "$log")"
  local rc=0
  ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 UBSAN_OPTIONS=print_stacktrace=1 \
    "$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
    -print_final_stats=1 -artifact_prefix="$art/" "$work" "$seeds" >"$log" 2>&1 || rc=$?
  local execs
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  if [ "$rc" -ne 0 ]; then
    echo "FAIL $name (exit $rc, ${execs:-?} executions); log $log, findings in $art:"
    ls "$art" || true
    grep -m1 -A30 -E 'ERROR: (libFuzzer|AddressSanitizer|LeakSanitizer)|runtime error' "$log" || tail -30 "$log"
    return 1
  fi
  printf '%-28s %10s executions in %s s\n' "$name" "${execs:-?}" "$seconds"
}

mapfile -t harnesses < <(grep -E "^($only)" "$dir/fuzzers.txt" || true)
[ ${#harnesses[@]} -gt 0 ] || { echo "fuzz: no harness matches '$only'" >&2; exit 1; }
echo "== fuzz: ${#harnesses[@]} harnesses, ${seconds} s each, $jobs at a time"
failed=0
pids=()
for line in "${harnesses[@]}"; do
  IFS=$'\t' read -r name bin seeds <<<"$line"
  run_one "$name" "$bin" "$seeds" &
  pids+=($!)
  if [ ${#pids[@]} -ge "$jobs" ]; then
    wait "${pids[0]}" || failed=1
    pids=("${pids[@]:1}")
  fi
done
for p in "${pids[@]}"; do wait "$p" || failed=1; done
if [ "$failed" -ne 0 ]; then
  echo "== fuzz: FAILED (see above)" >&2
  exit 1
fi
echo "== fuzz: all harnesses ran clean"
