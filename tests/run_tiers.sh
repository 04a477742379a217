#!/usr/bin/env bash
# `make test`'s suite on two cores, in four runs one after the other (each prints its slowest tests):
#
# 1. Everything but the real autopilots, six at a time: many tests wait on sockets and clocks.
# 2. PX4 v1.16 SIH flown by its clients over MAVLink (tests/autopilots/test_px4.py and the contract
#    tests), one at a time: two at a time, a SIH instance's estimator reset over and over and PX4
#    landed during a take-off (fresh-clone CI of 54a75b0).
# 3. PX4 flying our plant through the lockstep bridge, and MAVSDK's offboard examples on SIH, one
#    at a time: the bridge is a process of ours that must keep up with PX4 (two at a time, PX4's
#    estimator reset four times in 2 s on the plant), and the examples' client reads telemetry
#    without stamps (two at a time, one read a velocity 0.71 m/s off).
# 4. ArduPilot's tier, three at a time.
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
rcs=()
names=()

run() {  # name, then pytest's arguments; an interrupted run (exit 2) stops the rest
  local name=$1
  shift
  echo
  echo "=== ${name}"
  "$PY" -m pytest -q "$@"
  local rc=$?
  rcs+=("$rc")
  names+=("${name} ended after $(( $(date +%s) - start )) s (exit ${rc})")
  [ "$rc" -ne 2 ]
}

# the bundled vehicle's compiled kernel into the disk cache beside pytest's start-up (sitl/plant/chunk.py):
# a vehicle that boots meanwhile waits for it under a file lock instead of compiling its own
"$PY" -m sitl.plant.warm &
# shellcheck disable=SC2086 # the file lists are meant to split
run "everything but the firmware" -n 6 -m "not firmware" --durations=25 &&
  run "PX4 SIH and its clients, one at a time" -m "firmware and not ardupilot" \
    --durations=10 $PX4_SIH &&
  run "PX4 on our plant, and MAVSDK's examples on SIH, one at a time" -m "firmware and not ardupilot" \
    --durations=10 $PX4_ALONE &&
  run "ArduCopter SITL, three at a time" -n 3 --dist loadgroup -m "firmware and ardupilot" --durations=10
echo
printf '%s\n' "${names[@]}"
for rc in "${rcs[@]}"; do
  [ "$rc" -eq 0 ] || exit 1
done
[ "${#rcs[@]}" -eq 4 ]
