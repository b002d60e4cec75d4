#!/usr/bin/env bash
# Builds the test suite with AddressSanitizer + UndefinedBehaviorSanitizer (CPU code only) into
# build-asan/ and runs it; any sanitizer report fails the test that caused it (CI runs this).
# With --thread: ThreadSanitizer instead, into build-tsan/ (not in CI: Debian's libtbb is not
# instrumented, so TSan cannot see TBB's task hand-offs and reports them as races).
# Usage: scripts/sanitize.sh [--thread] [extra ctest arguments, e.g. -R 'Vgicp|Graph']
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ "${1:-}" == "--thread" ]]; then
  shift
  dir=build-tsan
  flags="-fsanitize=thread"
  export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1"
else
  dir=build-asan
  flags="-fsanitize=address,undefined -fno-sanitize-recover=undefined"
  export ASAN_OPTIONS=halt_on_error=1:abort_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1
  export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
  export LSAN_OPTIONS=suppressions=$PWD/scripts/lsan.supp
fi
launcher=()
# ccache, where installed, with paths relative to the checkout so another clone hits the same cache.
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache) && export CCACHE_BASEDIR="$PWD"
cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g1" \
  -DCMAKE_CXX_FLAGS="$flags -fno-omit-frame-pointer" -DCMAKE_EXE_LINKER_FLAGS="$flags" \
  -DGCMAP_CUDA=OFF -DGCMAP_BUILD_BENCH=OFF -DGCMAP_PYTHON=OFF "${launcher[@]}" >/dev/null
cmake --build "$dir" -j "$(nproc)" --target gcmap_cli gcmap_tests gcmap_e2e_tests
# Left out: the end-to-end scenarios and real-data runs that take 30 s to 10+ min under ASan on 2
# loaded cores (their code paths are covered by the smaller tests; the normal build runs them).
slow='^(SmallScenario\.|SmallDrive\.|PriorMapOfSmallBlock\.|RealisticRoutes\.|RealisticMerge\.|SessionRoundTrip\.|BagCli\.Map|BagSim\.|LoopScenario\.(ExplicitLoop|Retrieval|MapperBridges)|MapEntropy\.Thinner|Mapping\.Kitti00|Kitti07\.|DeskewDrive\.|OdometryTiming\.|Voxels/OdometryChecks\.|MergeOfSmallRoutes\.|MergeCommand\.|SimulatedDriveExport\.|GlobalTilt\.|ElevationCalibration\.SelfCalibration|InputAssumptionsE2E\.MapEstimates|GnssDrive\.|Quality\.|SmallDriveWithIntensity\.|InertialDrive\.)'
ctest --test-dir "$dir" --output-on-failure -j "$(nproc)" -E "$slow" "$@"
