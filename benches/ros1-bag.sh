#!/usr/bin/env bash
# ROS 1 bags (issue 50): `calib inspect` and `calib csrr` on a bag against a floor, the `rosbags`
# Python reader handing on the same messages (benches/ros1_floor.py).
#
#   benches/ros1-bag.sh BAG...                 # each bag, REPEAT (3) rounds, alternating
#   CALIB=target/release/calib PYTHON=/venv/bin/python REPEAT=5 benches/ros1-bag.sh run.bag
#
# Make a bag of 10^6 JointStates first (Python with numpy and rosbags):
#   sed 's/^rate_hz = 200.0/rate_hz = 60606.0/' testdata/scenarios/quick.toml > /tmp/big.toml
#   calib simulate /tmp/big.toml -o /tmp/run.csv
#   python benches/gen_ros1_bag.py /tmp/run.csv /tmp/run.bag --joints a,b [--compression lz4]
#
# Prints each command's CPU time (user + sys) and wall time per round, then the medians and the
# ratios to the floor. On a shared machine the CPU time is the steadier figure: wall time
# stretches with the other jobs' load.
set -euo pipefail

cd "$(dirname "$0")/.."
calib=${CALIB:-target/release/calib}
python=${PYTHON:-python3}
repeat=${REPEAT:-3}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
# "CPU WALL" seconds of one run of the command.
run() {
  /usr/bin/time -f '%U %S %e' -o "$out/time" "$@" > /dev/null 2>&1
  awk '{printf "%.3f %.3f\n", $1 + $2, $3}' "$out/time"
}

for bag in "$@"; do
  : > "$out/floor"; : > "$out/inspect"; : > "$out/csrr"
  for ((i = 1; i <= repeat; i++)); do
    f=$(run "$python" benches/ros1_floor.py "$bag")
    n=$(run "$calib" inspect "$bag")
    c=$(run "$calib" csrr "$bag" -o "$out/maps" --force)
    echo "# $bag round $i (CPU wall, s): floor $f, inspect $n, csrr $c"
    echo "$f" >> "$out/floor"; echo "$n" >> "$out/inspect"; echo "$c" >> "$out/csrr"
  done
  for what in floor inspect csrr; do
    cpu=$(cut -d' ' -f1 < "$out/$what" | median)
    w=$(cut -d' ' -f2 < "$out/$what" | median)
    echo "$what $cpu $w" >> "$out/medians"
  done
  awk -v bag="$bag" -v size="$(stat -c %s "$bag")" -v n="$repeat" '
    {cpu[$1] = $2; w[$1] = $3}
    END {
      printf "%s (%d bytes), medians of %d, CPU (wall) s: floor %.2f (%.2f); ", bag, size, n, cpu["floor"], w["floor"]
      printf "inspect %.2f (%.2f), %.2f× the floor; ", cpu["inspect"], w["inspect"], cpu["inspect"] / cpu["floor"]
      printf "csrr %.2f (%.2f), %.2f× the floor\n", cpu["csrr"], w["csrr"], cpu["csrr"] / cpu["floor"]
    }' "$out/medians"
  rm "$out/medians"
done
echo "# load after: $(uptime | sed 's/.*load/load/')"
