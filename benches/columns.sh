#!/usr/bin/env bash
# HDF5 and Parquet (issue 50): `calib inspect` on a file against a floor, the format's own
# library reading every column in one call (benches/columns_floor.py: h5py, pyarrow).
#
#   benches/columns.sh FILE...                 # each file, REPEAT (5) rounds, alternating
#   CALIB=target/release/calib PYTHON=/venv/bin/python REPEAT=5 benches/columns.sh run.h5
#
# Make the files of 10^6 samples first (Python with h5py and pyarrow):
#   sed 's/^rate_hz = 200.0/rate_hz = 60606.0/' testdata/scenarios/quick.toml > /tmp/big.toml
#   calib simulate /tmp/big.toml -o /tmp/run.csv
#   python benches/gen_columns.py /tmp/run.csv /tmp/run.h5 /tmp/run.parquet
#
# Prints each command's CPU time (user + sys) and wall time per round, the floor's own
# in-process time, then the medians and the ratios to the floor (whole process against whole
# process). On a shared machine the CPU time is the steadier figure.
set -euo pipefail

cd "$(dirname "$0")/.."
calib=${CALIB:-target/release/calib}
python=${PYTHON:-python3}
repeat=${REPEAT:-5}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
# "CPU WALL RSS_MB" of one run of the command; its standard output in $out/stdout.
run() {
  /usr/bin/time -f '%U %S %e %M' -o "$out/time" "$@" > "$out/stdout" 2>/dev/null
  awk '{printf "%.3f %.3f %.0f\n", $1 + $2, $3, $4 / 1024}' "$out/time"
}

echo "# load before: $(uptime | sed 's/.*load/load/')"
for file in "$@"; do
  : > "$out/floor"; : > "$out/inspect"; : > "$out/inproc"
  for ((i = 1; i <= repeat; i++)); do
    f=$(run "$python" benches/columns_floor.py "$file")
    inproc=$(sed 's/.*read in \([0-9.]*\) s/\1/' "$out/stdout")
    n=$(run "$calib" inspect "$file")
    grep -q ' samples over ' "$out/stdout" || { echo "calib inspect $file printed no samples" >&2; exit 1; }
    echo "# $file round $i (CPU wall s, MB): floor $f (in-process $inproc s), inspect $n"
    echo "$f" >> "$out/floor"; echo "$n" >> "$out/inspect"; echo "$inproc" >> "$out/inproc"
  done
  fc=$(cut -d' ' -f1 < "$out/floor" | median); fw=$(cut -d' ' -f2 < "$out/floor" | median)
  nc=$(cut -d' ' -f1 < "$out/inspect" | median); nw=$(cut -d' ' -f2 < "$out/inspect" | median)
  nm=$(cut -d' ' -f3 < "$out/inspect" | median); fi=$(median < "$out/inproc")
  awk -v f="$file" -v size="$(stat -c %s "$file")" -v n="$repeat" -v fc="$fc" -v fw="$fw" \
      -v fi="$fi" -v nc="$nc" -v nw="$nw" -v nm="$nm" 'BEGIN {
    printf "%s (%d bytes), medians of %d, CPU (wall) s: floor %.3f (%.3f), in-process %.3f; ", f, size, n, fc, fw, fi
    printf "inspect %.3f (%.3f), %.0f MB; CPU %.2f×, wall %.2f× the floor\n", nc, nw, nm, nc / fc, nw / fw
  }'
done
echo "# load after: $(uptime | sed 's/.*load/load/')"
