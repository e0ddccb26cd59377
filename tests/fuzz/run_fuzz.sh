#!/usr/bin/env bash
# Runs one libFuzzer target of tests/fuzz for a bounded time (ctest label `fuzz`; a nightly job runs it longer).
#   run_fuzz.sh FUZZER SEED_DIR WORK_DIR [libFuzzer options...]
# The committed seeds (SEED_DIR: read, never written) are run first, so every regression input found before is
# replayed; new inputs go to WORK_DIR/corpus, a crash, leak, timeout or out-of-memory input to WORK_DIR/artifacts
# (add it to SEED_DIR with the fix). SEED_DIR.dict, when present, is the target's dictionary.
# Exit status: the fuzzer's (0 = nothing found).
# MYOSKIN_FUZZ_FRESH=1 (the ctest tier, with -seed=1) starts WORK_DIR/corpus empty, so every run of the tier
# fuzzes the same inputs in the same order from the committed seeds (a nightly run keeps its grown corpus).
set -euo pipefail
fuzzer="$1" seeds="$2" work="$3"
shift 3
[ -x "$fuzzer" ] || { echo "run_fuzz.sh: $fuzzer is not built (the sanitizer build: ./myoskin.sh build)" >&2; exit 1; }
[ -d "$seeds" ] && [ -n "$(ls -A "$seeds")" ] || { echo "run_fuzz.sh: no seeds in $seeds" >&2; exit 1; }
[ "${MYOSKIN_FUZZ_FRESH:-0}" = 0 ] || rm -rf "$work/corpus"
mkdir -p "$work/corpus" "$work/artifacts"
dict=()
[ -f "$seeds.dict" ] && dict=(-dict="$seeds.dict")
export TMPDIR="$work"
exec "$fuzzer" -timeout=25 -rss_limit_mb=2560 -malloc_limit_mb=2048 -print_final_stats=1 \
  -artifact_prefix="$work/artifacts/" "${dict[@]}" "$@" "$work/corpus" "$seeds"
