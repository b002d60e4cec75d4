#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ (clang, ASan+UBSan) into build-fuzz/ and runs each on its
# seed corpus for a bounded time. Fails on any crash, sanitizer report, uncaught exception, timeout,
# or allocation over the malloc limit (a size taken from a header without checking it).
# Usage: scripts/fuzz_smoke.sh [SECONDS_PER_TARGET (20)] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-20}
shift || true
launcher=()
# ccache, where installed, with paths relative to the checkout so another clone hits the same cache.
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache) && export CCACHE_BASEDIR="$PWD"
cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ -DGCMAP_FUZZ=ON \
  -DGCMAP_CUDA=OFF -DGCMAP_BUILD_TESTS=OFF -DGCMAP_BUILD_BENCH=OFF "${launcher[@]}" >/dev/null
cmake --build build-fuzz -j "$(nproc)" --target gcmap_fuzz

targets=("$@")
if ((${#targets[@]} == 0)); then
  for t in build-fuzz/fuzz/fuzz_*; do targets+=("$(basename "$t")"); done
fi
work=build-fuzz/smoke
rm -rf "$work"
mkdir -p "$work"
failed=()
for name in "${targets[@]}"; do
  mkdir -p "$work/$name"
  # New inputs go to the scratch corpus first on the line; the committed seeds are only read.
  if build-fuzz/fuzz/"$name" "$work/$name" "fuzz/corpus/$name" -max_total_time="$seconds" -timeout=10 \
      -rss_limit_mb=2048 -malloc_limit_mb=256 -print_final_stats=1 -artifact_prefix="$work/$name-" \
      >"$work/$name.log" 2>&1; then
    stats=$(grep -E '^#[0-9]+.*(DONE|pulse)' "$work/$name.log" | tail -1 | grep -oE 'cov: [0-9]+ ft: [0-9]+|exec/s: [0-9]+' | tr '\n' ' ')
    echo "ok   $name: ${stats}"
  else
    echo "FAIL $name (log: $work/$name.log, input: $(ls "$work/$name"-* 2>/dev/null | head -1))"
    grep -E 'ERROR|SUMMARY|runtime error|uncaught|==[0-9]+==' "$work/$name.log" | head -20
    failed+=("$name")
  fi
done
if ((${#failed[@]})); then
  echo "fuzz smoke: ${#failed[@]} target(s) failed: ${failed[*]}" >&2
  exit 1
fi
echo "fuzz smoke: ${#targets[@]} targets, ${seconds} s each, no findings"
