#!/usr/bin/env bash
# Work that must grow linearly with its input (issue 52), timed with a release `calib`:
#   - `calib import --format simplefoc` of a printLUT() table of N entries, one a line;
#   - `calib moteus-dump --points N` of a dump of 7 pole pairs, 4000 samples each way;
#   - `calib plan csrr --sessions K` and `calib plan multihead --heads K` to order 30.
# Prints the median wall time (and the largest peak RSS) of REPEAT runs (default 3) per size.
#
#   benches/growth.sh [CALIB]        # CALIB: a release binary (default: builds target/release/calib)
#
# Sizes: IMPORT_SIZES (default "10000 100000 1000000 3600000", the last the table limit),
# POINTS_SIZES (default "10000 100000 1000000 3600000"), ANGLE_SIZES (default "100 300 1000",
# the last the plan limit). A size that runs past TIMEOUT seconds (default 120) prints "> TIMEOUT".
set -euo pipefail
cd "$(dirname "$0")/.."
CALIB=${1:-}
if [[ -z "$CALIB" ]]; then
    cargo build --release -p calib-cli >&2
    CALIB=target/release/calib
fi
REPEAT=${REPEAT:-3}
TIMEOUT=${TIMEOUT:-120}
IMPORT_SIZES=${IMPORT_SIZES:-"10000 100000 1000000 3600000"}
POINTS_SIZES=${POINTS_SIZES:-"10000 100000 1000000 3600000"}
ANGLE_SIZES=${ANGLE_SIZES:-"100 300 1000"}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "# $(uptime)"

# Median wall seconds and largest peak RSS (MB) of REPEAT runs of "$@".
measure() {
    local times=() rss=0
    for _ in $(seq "$REPEAT"); do
        rm -rf "$work"/out*
        local rc=0
        /usr/bin/time -f '%e %M' -o "$work/time" timeout "$TIMEOUT" "$@" >/dev/null 2>&1 || rc=$?
        if [[ $rc -eq 124 ]]; then echo "> ${TIMEOUT} s"; return; fi
        if [[ $rc -ne 0 ]]; then echo "failed (exit $rc): $*"; return; fi
        read -r t m < <(tail -1 "$work/time")
        times+=("$t")
        (( m > rss )) && rss=$m
    done
    printf '%s s (median of %s), %d MB\n' \
        "$(printf '%s\n' "${times[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')" \
        "$REPEAT" $((rss / 1024))
}

for n in $IMPORT_SIZES; do
    python3 - "$n" > "$work/lut.h" <<'PY'
import sys
n = int(sys.argv[1])
print(f"uint16_t calibrationLut[{n}] = {{")
for k in range(n):
    print(f"  {32767 + (k * 37) % 200 - 100},")
print("};")
PY
    printf 'import  %8s entries: ' "$n"
    measure "$CALIB" import "$work/lut.h" --format simplefoc -o "$work/out.csv"
done

python3 - > "$work/dump.txt" <<'PY'
# 7 pole pairs, 4000 samples each way, a 30-count encoder error at order 1.
import math
print("CAL start")
n = 4000
for d, ks in ((1, range(n)), (2, range(n - 1, -1, -1))):
    for k in ks:
        phase = (k * 7 * 65536 // n) % 65536
        enc = (k * 65536 // n + round(30 * math.sin(2 * math.pi * k / n))) % 65536
        print(d, phase, enc)
print("CAL done")
PY
for n in $POINTS_SIZES; do
    printf 'moteus-dump --points %8s: ' "$n"
    measure "$CALIB" moteus-dump "$work/dump.txt" --points "$n" -o "$work/out-md"
done

for k in $ANGLE_SIZES; do
    printf 'plan csrr --sessions %5s: ' "$k"
    measure "$CALIB" plan csrr --max-order 30 --sessions "$k"
    printf 'plan multihead --heads %5s: ' "$k"
    measure "$CALIB" plan multihead --max-order 30 --heads "$k"
done
