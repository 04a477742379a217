#!/usr/bin/env bash
# `make test`'s suite on two cores: everything but the real autopilots with most of PX4's tier
# beside it, then PX4's MAVSDK examples alone, then ArduPilot's tier.
#
# 1. Everything but the real autopilots, six at a time (many tests wait on sockets and clocks) and
#    under `nice -n 5` (NICE): its flights whose subject is control run in lockstep, so a busy host
#    changes how long they take, not what they measure. Beside it, at normal priority, PX4's tier
#    one test at a time: PX4 SIH flies at a fixed speed-up of the wall clock, and its clients must
#    get the CPU when they ask for it. Its output follows the first run's.
# 2. PX4's runs of MAVSDK's offboard examples, alone: their client reads telemetry without stamps
#    (beside the rest, one read a velocity 1.3 m/s off what PX4 had reached).
# 3. ArduPilot's tier, three at a time (three ArduCopters and their companions take both cores;
#    beside the rest, a square lost its telemetry for 2.9 s).
# Each firmware test boots its autopilot on instances of its worker's own (tests/helpers/firmware.py);
# a module whose tests share one boot stays on one worker (loadgroup). Where PX4 or ArduCopter SITL
# is not found, each of its tests is reported skipped with the reason. Each run prints its slowest
# tests. Exits 0 only if all passed. PY: the interpreter (make passes the venv's).
# Measured: docs/benchmarks.md, "The test suite".
set -u
PY=${PY:-.venv/bin/python}
NICE=${NICE:-5}
EXAMPLES=tests/contract/test_mavsdk_examples.py
logs=$(mktemp -d)
trap 'rm -rf "$logs"' EXIT
start=$(date +%s)

(
  "$PY" -m pytest -q -o cache_dir=.pytest_cache/px4 -m "firmware and not ardupilot" --deselect "$EXAMPLES" \
    --durations=10 >"$logs/px4" 2>&1
  echo "$? $(( $(date +%s) - start ))" >"$logs/px4.rc"
) &

nice -n "$NICE" "$PY" -m pytest -q -n 6 -m "not firmware" --durations=25
main=$?
main_s=$(( $(date +%s) - start ))
wait
read -r px4 px4_s <"$logs/px4.rc" 2>/dev/null || { px4=1; px4_s=-; }
echo
echo "=== beside the above, the real-autopilot tier: PX4 v1.16 SIH"
cat "$logs/px4"
examples=2
ardupilot=2
if [ "$px4" -ne 2 ] && [ "$main" -ne 2 ]; then  # 2: interrupted (Ctrl-C reaches every run)
  echo
  echo "=== then PX4's runs of MAVSDK's offboard examples, alone"
  "$PY" -m pytest -q -o cache_dir=.pytest_cache/px4 -m firmware "$EXAMPLES" --durations=4
  examples=$?
fi
examples_s=$(( $(date +%s) - start ))
if [ "$examples" -ne 2 ]; then
  echo
  echo "=== then the real-autopilot tier: ArduCopter SITL"
  "$PY" -m pytest -q -o cache_dir=.pytest_cache/ardupilot -n 3 --dist loadgroup -m "firmware and ardupilot" \
    --durations=10
  ardupilot=$?
fi
echo
echo "tiers: everything but the firmware ended after ${main_s} s (exit ${main}), PX4's beside it after" \
     "${px4_s} s (exit ${px4}), then PX4's MAVSDK examples after ${examples_s} s (exit ${examples}), then" \
     "ArduPilot's after $(( $(date +%s) - start )) s (exit ${ardupilot})"
[ "$main" -eq 0 ] && [ "$px4" -eq 0 ] && [ "$examples" -eq 0 ] && [ "$ardupilot" -eq 0 ]
