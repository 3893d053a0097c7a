#!/usr/bin/env bash
# Farm overhead benchmark (docs/farm.md): a >= 60 s render of the demo scene as
# 4 sample splits through a private single-node Slurm against one process using the
# same cores. Needs root and the slurm-wlm/munge packages (make deps) and a build.
# GLIMMER_FARM_BENCH_ARGS overrides the render size (default: 640x400, 240 samples; GLIMMER_FARM_BENCH_REPS repetitions, 2).
set -euo pipefail
build=${BUILD:-build}
cmake --build "$build" --target test_bridge_images glimmer > /dev/null
exec "$build/test_bridge_images" --gtest_also_run_disabled_tests \
  --gtest_filter='Slurm.DISABLED_BenchFourWaySplitOverheadVsOneProcess'
