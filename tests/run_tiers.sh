#!/usr/bin/env bash
# `make test`'s suite: everything but the real autopilots with PX4's tier beside it, then
# ArduPilot's tier, on two cores.
#
# - Everything but the real autopilots, six at a time (many tests wait on sockets and clocks) and
#   under `nice -n 5` (NICE): its flights whose subject is control run in lockstep, so a busy host
#   changes how long they take, not what they measure.
# - Beside it, at normal priority, PX4's tier, one test at a time: PX4 SIH flies at a fixed speed-up
#   of the wall clock and must get the CPU when it asks for it (starved, a PX4 flight failed:
#   docs/benchmarks.md, "The test suite"). Its output follows the first run's.
# - Then ArduPilot's tier alone, three at a time (three ArduCopters and their companions take both
#   cores; beside the rest, a square lost its telemetry for 2.9 s).
# Each firmware test boots its autopilot on instances of its worker's own (tests/helpers/firmware.py);
# a module whose tests share one boot stays on one worker (loadgroup). Where PX4 or ArduCopter SITL
# is not found, each of its tests is reported skipped with the reason. Each run prints its slowest
# tests. Exits 0 only if all three passed. PY: the interpreter (make passes the venv's).
set -u
PY=${PY:-.venv/bin/python}
NICE=${NICE:-5}
logs=$(mktemp -d)
trap 'rm -rf "$logs"' EXIT
start=$(date +%s)

(
  "$PY" -m pytest -q -o cache_dir=.pytest_cache/px4 -m "firmware and not ardupilot" --durations=10 \
    >"$logs/px4" 2>&1
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
echo
echo "=== then the real-autopilot tier: ArduCopter SITL"
ardupilot=2
if [ "$px4" -ne 2 ] && [ "$main" -ne 2 ]; then  # 2: interrupted (Ctrl-C reaches every run)
  "$PY" -m pytest -q -o cache_dir=.pytest_cache/ardupilot -n 3 --dist loadgroup -m "firmware and ardupilot" \
    --durations=10
  ardupilot=$?
fi
echo
echo "tiers: everything but the firmware ended after ${main_s} s (exit ${main}), PX4's beside it after" \
     "${px4_s} s (exit ${px4}), then ArduPilot's after $(( $(date +%s) - start )) s (exit ${ardupilot})"
[ "$main" -eq 0 ] && [ "$px4" -eq 0 ] && [ "$ardupilot" -eq 0 ]
