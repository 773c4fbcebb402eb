#!/usr/bin/env bash
# calib's commands against the floor, on one large JointState MCAP, in one run.
#
#   benches/end-to-end.sh                    # 10 M samples, 5 runs of each
#   SAMPLES=2000000 REPEAT=3 benches/end-to-end.sh
#   KEEP=/tmp/e2e benches/end-to-end.sh      # keep the log (and reuse it next time)
#   CALIB=/path/to/other/calib benches/end-to-end.sh   # measure another build beside the floor
#
# The log: two 72-pole-pair sensors and a reference as in testdata/scenarios/csrr72.toml,
# 5 CSRR sessions at 60 r/min sampled at 10 kHz, zstd chunks, simulated with `calib simulate`.
# The floor: `mcap_floor` (crates/calib-io/examples/mcap_floor.rs) — the mcap crate's
# MessageStream over the memory-mapped file plus the least decode of each JointState's
# positions, one thread. Then, alternating with it REPEAT times each:
#   inspect    calib inspect LOG --json
#   csrr       calib csrr LOG -o OUT -q
#   reference  calib reference LOG --dut b --ref ref -o OUT -q
#   apply      calib apply OUT/a.csv LOG --channel a -o LOG2   (reads, corrects, re-compresses),
#              beside floor+write: `mcap_floor LOG --write COPY`, the floor plus every message
#              written unchanged into a new MCAP through the mcap crate's Writer (the input's
#              zstd, default chunk size and level, one thread) — the floor of a rewriter
# Then on a second log, a coast for `calib tdr`: testdata/scenarios/spindown.toml (an air-bearing
# spin-down from 600 r/min, two channels) recorded for COAST_S s at COAST_HZ (default 100 s at
# 100 kHz: 10,000,001 samples, 600 → 80 r/min), the floor on it alternating REPEAT times with
#   tdr        calib tdr COAST --channel enc -o OUT -q
# (COAST_HZ=0 leaves it out: a tdr run takes minutes, the fit and not the reading.)
# It prints each one's median wall and CPU time, its peak RSS, and the ratio of its median wall
# time to the floor's (apply's: to floor+write's). The log is read from the page cache (a first,
# unmeasured read warms it).
set -euo pipefail

cd "$(dirname "$0")/.."
samples=${SAMPLES:-10000000}
repeat=${REPEAT:-5}
rate_hz=10000
speed_rpm=60

if [[ ! -x /usr/bin/time ]]; then
  echo "installing GNU time (apt-get install time)" >&2
  apt-get install -y time >&2
fi

cargo build --release --locked -p calib-cli >&2
cargo build --release --locked -p calib-io --example mcap_floor >&2
calib=${CALIB:-$PWD/target/release/calib}
floor="$PWD/target/release/examples/mcap_floor"
if [[ -n ${KEEP:-} ]]; then
  work=$KEEP
  mkdir -p "$work"
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi

# Per session: ramps of 1 s, a 1 s pause; 4 relative turns of 2 s; 28 s besides the revolutions.
revolutions=$(awk -v n="$samples" -v r="$rate_hz" -v s="$speed_rpm" \
  'BEGIN{printf "%d", (n / r - 28) * s / 60 / 5 + 0.5}')
scenario="$work/run.toml"
log="$work/run.mcap"
sed -e "/^rate_hz/s/.*/rate_hz = $rate_hz.0/" -e "/^speed_rpm/s/.*/speed_rpm = $speed_rpm.0/" \
  -e "/^revolutions/s/.*/revolutions = $revolutions.0/" \
  testdata/scenarios/csrr72.toml > "$scenario"
# Simulates SCENARIO into LOG unless LOG was made from the same scenario (kept in LOG.toml).
simulate_once() {
  if [[ ! -s $2 ]] || ! cmp -s "$1" "$2.toml"; then
    echo "simulating $1 → $2" >&2
    "$calib" simulate "$1" -o "$2" -q >&2
    cp "$1" "$2.toml"
  fi
}
simulate_once "$scenario" "$log"
"$floor" "$log" >&2
"$calib" csrr "$log" -o "$work/table" -q > /dev/null

# One line: wall_s cpu_s max_rss_kb.
measure() {
  /usr/bin/time -f '%e %U %S %M' -o "$work/time.txt" "$@" > /dev/null
  awk '{printf "%.3f %.3f %d\n", $1, $2 + $3, $4}' "$work/time.txt"
}
median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

names=(floor inspect csrr reference floor+write apply)
run() {
  case $1 in
    floor) measure "$floor" "$log" ;;
    inspect) measure "$calib" inspect "$log" --json ;;
    csrr) measure "$calib" csrr "$log" -o "$work/out-csrr" -q ;;
    reference) measure "$calib" reference "$log" --dut b --ref ref -o "$work/out-ref" -q ;;
    floor+write) rm -f "$work/floor-copy.mcap"
      measure "$floor" "$log" --write "$work/floor-copy.mcap" ;;
    apply) rm -f "$work/applied.mcap"
      measure "$calib" apply "$work/table/a.csv" "$log" --channel a -o "$work/applied.mcap" -q ;;
  esac
}
for name in "${names[@]}"; do : > "$work/$name.txt"; done
for ((i = 1; i <= repeat; i++)); do
  echo "round $i/$repeat ($(uptime | sed 's/.*load/load/'))" >&2
  for name in "${names[@]}"; do run "$name" >> "$work/$name.txt"; done
done

echo "# $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores, calib $(git rev-parse --short HEAD), $(stat -c %s "$log" | awk '{printf "%.0f MB", $1 / 1e6}') log, $repeat runs each"
floor_s=$(cut -d' ' -f1 "$work/floor.txt" | median)
write_s=$(cut -d' ' -f1 "$work/floor+write.txt" | median)
printf '%-11s %10s %10s %10s %9s\n' command "wall s" "cpu s" "peak MB" "÷ floor"
for name in "${names[@]}"; do
  wall=$(cut -d' ' -f1 "$work/$name.txt" | median)
  cpu=$(cut -d' ' -f2 "$work/$name.txt" | median)
  rss=$(cut -d' ' -f3 "$work/$name.txt" | sort -g | tail -1)
  base=$floor_s
  [[ $name == apply ]] && base=$write_s # apply: ÷ floor+write
  awk -v n="$name" -v w="$wall" -v c="$cpu" -v r="$rss" -v f="$base" \
    'BEGIN{printf "%-11s %10.2f %10.2f %10.0f %9.2f\n", n, w, c, r / 1024, w / f}'
done
echo "# load after: $(uptime | sed 's/.*load/load/')"

# The coast log for `calib tdr`, and tdr against the floor on that log.
coast_hz=${COAST_HZ:-100000}
coast_s=${COAST_S:-100}
if [[ $coast_hz != 0 ]]; then
  coast_scenario="$work/coast.toml"
  coast="$work/coast.mcap"
  sed -e "/^rate_hz/s/.*/rate_hz = $coast_hz.0/" -e "/^duration_s/s/.*/duration_s = $coast_s.0/" \
    testdata/scenarios/spindown.toml > "$coast_scenario"
  simulate_once "$coast_scenario" "$coast"
  "$floor" "$coast" >&2
  : > "$work/floor-coast.txt"
  : > "$work/tdr.txt"
  for ((i = 1; i <= repeat; i++)); do
    echo "coast round $i/$repeat ($(uptime | sed 's/.*load/load/'))" >&2
    measure "$floor" "$coast" >> "$work/floor-coast.txt"
    measure "$calib" tdr "$coast" --channel enc -o "$work/out-tdr" -q >> "$work/tdr.txt"
  done
  echo "# $(stat -c %s "$coast" | awk '{printf "%.0f MB", $1 / 1e6}') coast log, $repeat runs each"
  floor_s=$(cut -d' ' -f1 "$work/floor-coast.txt" | median)
  for name in floor-coast tdr; do
    wall=$(cut -d' ' -f1 "$work/$name.txt" | median)
    cpu=$(cut -d' ' -f2 "$work/$name.txt" | median)
    rss=$(cut -d' ' -f3 "$work/$name.txt" | sort -g | tail -1)
    awk -v n="$name" -v w="$wall" -v c="$cpu" -v r="$rss" -v f="$floor_s" \
      'BEGIN{printf "%-11s %10.2f %10.2f %10.0f %9.2f\n", n, w, c, r / 1024, w / f}'
  done
  echo "# load after: $(uptime | sed 's/.*load/load/')"
fi
