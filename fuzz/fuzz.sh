#!/usr/bin/env bash
# Runs every fuzz target for SECONDS (default 600) one after the other and prints, per
# target, AFL++'s execution count, corpus size and crash count. Needs cargo-afl (README.md).
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-600}
export AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1 AFL_NO_UI=1
cargo afl build --release
for target in ply xyz off obj scene snapshot; do
    seeds=seeds/$target
    [ "$target" = xyz ] && seeds=seeds/xyz
    cargo afl fuzz -V "$seconds" -i "$seeds" -o "out/$target" "target/release/$target" >"out-$target.log" 2>&1 || true
    stats=out/$target/default/fuzzer_stats
    echo "$target: $(grep -E '^(execs_done|corpus_count|saved_crashes|saved_hangs|run_time)' "$stats" | tr -s ' ' | tr '\n' ' ')"
done
