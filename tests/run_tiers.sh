#!/usr/bin/env bash
# `make test`'s suite: three pytest runs at once on two cores, their output one after the other.
#
# - Everything but the real autopilots, six at a time (many tests wait on sockets and clocks) and
#   under `nice -n 10`: its flights whose subject is control run in lockstep, so a busy host changes
#   how long they take, not what they measure.
# - Beside it, at normal priority, the real-autopilot tier: PX4 SIH and ArduCopter SITL fly at fixed
#   speed-ups of the wall clock and must get the CPU when they ask for it (starved, a PX4 flight
#   failed: docs/benchmarks.md, "The test suite"). PX4's tests one at a time, then ArduPilot's three
#   at a time, each test booting its autopilot on instances of its worker's own
#   (tests/helpers/firmware.py); a module whose tests share one boot stays on one worker (loadgroup).
#   Where PX4 or ArduCopter SITL is not found, each of its tests is reported skipped with the reason.
#
# Each run prints its slowest tests; the tier's output follows the main run's. Exits 0 only if all
# passed. PY: the interpreter (make passes the venv's).
set -u
PY=${PY:-.venv/bin/python}
logs=$(mktemp -d)
trap 'rm -rf "$logs"' EXIT
start=$(date +%s)

(
  "$PY" -m pytest -q -o cache_dir=.pytest_cache/px4 -m "firmware and not ardupilot" --durations=10 \
    >"$logs/px4" 2>&1
  rc=$?
  echo "$rc $(( $(date +%s) - start ))" >"$logs/px4.rc"
  if [ "$rc" -ne 2 ]; then  # 2: interrupted (Ctrl-C reaches every run: same process group)
    "$PY" -m pytest -q -o cache_dir=.pytest_cache/ardupilot -n 3 --dist loadgroup \
      -m "firmware and ardupilot" --durations=10 >"$logs/ardupilot" 2>&1
    echo "$? $(( $(date +%s) - start ))" >"$logs/ardupilot.rc"
  fi
) &

nice -n 10 "$PY" -m pytest -q -n 6 -m "not firmware" --durations=25
main=$?
main_s=$(( $(date +%s) - start ))
wait

read -r px4 px4_s <"$logs/px4.rc" 2>/dev/null || { px4=1; px4_s=-; }
read -r ardupilot ardupilot_s <"$logs/ardupilot.rc" 2>/dev/null || { ardupilot=1; ardupilot_s=-; }
echo
echo "=== the real-autopilot tier, run beside the above: PX4 v1.16 SIH, then ArduCopter SITL"
cat "$logs/px4"
cat "$logs/ardupilot" 2>/dev/null
echo
echo "tiers: everything but the firmware ended after ${main_s} s (exit ${main}); beside it PX4's after" \
     "${px4_s} s (exit ${px4}), then ArduPilot's after ${ardupilot_s} s (exit ${ardupilot})"
[ "$main" -eq 0 ] && [ "$px4" -eq 0 ] && [ "$ardupilot" -eq 0 ]
