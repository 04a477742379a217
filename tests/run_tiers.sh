#!/usr/bin/env bash
# `make test`'s suite on two cores (each run prints its slowest tests):
#
# 1. Everything but the real autopilots, six at a time: many tests wait on sockets and clocks.
# 2. Then two lanes side by side (each of these runs alone keeps about half a core busy, waiting on
#    its flights' wall time: 0.84 and 0.43 cores measured, docs/benchmarks.md):
#    a. ArduPilot's tier, three at a time;
#    b. PX4 flying our plant through the lockstep bridge, then MAVSDK's offboard examples on SIH, one
#       at a time: the bridge is a process of ours that must keep up with PX4 (two at a time, PX4's
#       estimator reset four times in 2 s on the plant), and the examples' client reads telemetry
#       without stamps (two at a time, one read a velocity 0.71 m/s off). This lane takes PX4
#       instances 5-9 (FIRMWARE_WORKERS_BEFORE, tests/helpers/firmware.py).
# 3. Then PX4 v1.16 SIH flown by its clients (tests/autopilots/test_px4.py and the contract tests),
#    one at a time and alone: run as root, PX4 gives its threads real-time priorities and preempts
#    every other process's, so beside it the bridge fell behind (an estimator reset on the plant,
#    CI of c5cb00f) and an example's client read late; two SIH instances at a time, an estimator
#    reset over and over and PX4 landed during a take-off (CI of 54a75b0).
# Each firmware test boots its autopilot on instances of its worker's own (tests/helpers/firmware.py);
# a module whose tests share one boot stays on one worker (loadgroup). Where PX4 or ArduCopter SITL
# is not found, each of its tests is reported skipped with the reason. Running the firmware beside
# the rest of the suite was tried and not kept: each of four fresh-clone runs failed a different
# test on one side or the other (docs/benchmarks.md, "The test suite"). Exits 0 only if all passed.
# PY: the interpreter (make passes the venv's).
set -u
PY=${PY:-.venv/bin/python}
PX4_SIH="tests/autopilots/test_px4.py tests/contract/test_contract.py"
PX4_ALONE="tests/autopilots/test_firmware_plant.py tests/autopilots/test_firmware_estimator.py
  tests/autopilots/test_firmware_cli.py tests/contract/test_firmware_on_the_plant.py tests/contract/test_mavsdk_examples.py"
start=$(date +%s)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

run() {  # log file, name, then pytest's arguments; an interrupted run (exit 2) stops its lane
  local log=$1 name=$2
  shift 2
  { echo; echo "=== ${name}"; } >> "$log"
  "$PY" -m pytest -q "$@" >> "$log" 2>&1
  local rc=$?
  echo "${rc} ${name} ended after $(( $(date +%s) - start )) s (exit ${rc})" >> "$out/status"
  [ "$rc" -ne 2 ]
}

# the bundled vehicle's compiled kernel into the disk cache beside pytest's start-up (sitl/plant/chunk.py):
# a vehicle that boots meanwhile waits for it under a file lock instead of compiling its own
"$PY" -m sitl.plant.warm &
run /dev/stdout "everything but the firmware" -n 6 -m "not firmware" --durations=25
main_rc=$(tail -1 "$out/status" | cut -d' ' -f1)
if [ "$main_rc" -ne 2 ]; then
  run "$out/a.log" "ArduCopter SITL, three at a time" -n 3 --dist loadgroup -m "firmware and ardupilot" \
    --durations=10 &
  # shellcheck disable=SC2086 # the file lists are meant to split
  FIRMWARE_WORKERS_BEFORE=1 run "$out/b.log" "PX4 on our plant, and MAVSDK's examples on SIH, one at a time" \
    -m "firmware and not ardupilot" --durations=10 $PX4_ALONE &
  wait
  cat "$out/a.log" "$out/b.log"
  # shellcheck disable=SC2086
  if ! grep -q '^2 ' "$out/status"; then
    run /dev/stdout "PX4 SIH and its clients, one at a time" -m "firmware and not ardupilot" --durations=10 $PX4_SIH
  fi
fi
echo
cut -d' ' -f2- "$out/status"
[ "$(wc -l < "$out/status")" -eq 4 ] && ! grep -qv '^0 ' "$out/status"
