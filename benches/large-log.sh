#!/usr/bin/env bash
# End to end on large logs: how long `calib csrr` takes against reading and decoding the same
# log, and how much memory each needs, as the log grows.
#
#   benches/large-log.sh                      # 1e7 and 2e7 samples
#   benches/large-log.sh 10000000             # one size
#   KEEP=/tmp/big benches/large-log.sh        # keep the logs (and reuse them on the next run)
#   REPEAT=1 benches/large-log.sh             # one run per measurement instead of 3
#
# For each size N it writes a scenario (two 72-pole-pair sensors as in
# testdata/scenarios/csrr72.toml; 5 sessions at 60 r/min sampled at 10 kHz, the revolutions per
# session chosen to give ~N samples), simulates it into a JointState MCAP with `calib simulate`,
# then runs under /usr/bin/time -v, REPEAT times each, alternating:
#   (a) read + decode:  calib inspect LOG --json > /dev/null
#       (the reader's full stream through the per-sample inspector; an upper bound on bare
#       reading and decoding, for which see `cargo bench -p calib-io --bench ingest_mcap`)
#   (b) calibration:    calib csrr LOG -o OUT
# and prints the median wall and CPU (user + sys) time of each, the ratios (b)/(a), and the peak
# resident set size (largest over the runs). On a shared machine the CPU time is the steadier
# figure: wall time stretches with the other jobs' load. While each command runs, /proc/PID/status is polled every 50 ms for
# the peak of RssAnon (heap: what the process itself allocated) and RssFile (pages of the
# memory-mapped log that happen to be resident; the kernel can drop them at any time).
# The log is read from the page cache (it was just written), as on a second run over a log.
#
# The bar (issue): calibration < 2× read + decode; peak memory < 500 MB whatever the log length.
set -euo pipefail

cd "$(dirname "$0")/.."
sizes=("$@")
[[ ${#sizes[@]} -gt 0 ]] || sizes=(10000000 20000000)
repeat=${REPEAT:-3}
rate_hz=10000
speed_rpm=60

if [[ ! -x /usr/bin/time ]]; then
  echo "installing GNU time (apt-get install time)" >&2
  sudo apt-get install -y time >&2 || apt-get install -y time >&2
fi

cargo build --release -p calib-cli >&2
calib="$PWD/target/release/calib"
if [[ -n ${KEEP:-} ]]; then
  work=$KEEP
  mkdir -p "$work"
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi

# Runs "$@" under /usr/bin/time -v, its standard output to /dev/null, polling its /proc status.
# Prints one line:
# wall_s cpu_s(user+sys) max_rss_kb peak_rss_anon_kb peak_rss_file_kb
measure() {
  local tfile="$work/time.txt"
  /usr/bin/time -v -o "$tfile" "$@" > /dev/null &
  local tpid=$! cpid="" anon=0 file=0 a f
  while kill -0 "$tpid" 2>/dev/null; do
    [[ -n $cpid ]] || cpid=$(pgrep -P "$tpid" || true)
    if [[ -n $cpid && -r /proc/$cpid/status ]]; then
      read -r a f < <(awk '/^RssAnon:/{a=$2} /^RssFile:/{f=$2} END{print a+0, f+0}' \
        "/proc/$cpid/status" 2>/dev/null || echo "0 0")
      ((a > anon)) && anon=$a
      ((f > file)) && file=$f
    fi
    sleep 0.05
  done
  wait "$tpid"
  awk -v anon="$anon" -v file="$file" '
    /Elapsed \(wall clock\)/ { n = split($NF, p, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + p[i] }
    /User time|System time/ { cpu += $NF }
    /Maximum resident set size/ { rss = $NF }
    END { printf "%.2f %.2f %d %d %d\n", s, cpu, rss, anon, file }' "$tfile"
}

median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
max() { sort -g | tail -1; }
mb() { awk -v kb="$1" 'BEGIN{printf "%.0f", kb / 1024}'; }

echo "# $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores, $(uname -r), calib $(git rev-parse --short HEAD)"
printf '%-9s %7s  %-16s %-16s %-12s  %-26s %-26s\n' samples log_MB "read s wall/cpu" \
  "csrr s wall/cpu" "ratio w/cpu" "read peak MB rss/anon/file" "csrr peak MB rss/anon/file"
for n in "${sizes[@]}"; do
  # Per session: 1 s ramp up, the revolutions, 1 s ramp down (ramps cover half a revolution
  # each), 1 s pause; plus 4 turns of 2 s with a 1 s pause and a first pause: 28 s in all.
  revolutions=$(awk -v n="$n" -v r="$rate_hz" -v s="$speed_rpm" \
    'BEGIN{printf "%d", (n / r - 28) * s / 60 / 5 + 0.5}')
  scenario="$work/run-$n.toml"
  log="$work/run-$n.mcap"
  sed -e "/^rate_hz/s/.*/rate_hz = $rate_hz.0/" -e "/^speed_rpm/s/.*/speed_rpm = $speed_rpm.0/" \
    -e "/^revolutions/s/.*/revolutions = $revolutions.0/" \
    testdata/scenarios/csrr72.toml > "$scenario"
  if [[ ! -s $log ]] || ! cmp -s "$scenario" "$log.toml"; then
    echo "simulating $n samples ($revolutions revolutions per session) → $log" >&2
    start=$(date +%s.%N)
    "$calib" simulate "$scenario" -o "$log" >&2
    cp "$scenario" "$log.toml"
    echo "  simulate: $(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b - a}') s" >&2
  fi
  : > "$work/read.txt"
  : > "$work/csrr.txt"
  for ((i = 0; i < repeat; i++)); do
    echo "  run $((i + 1))/$repeat ($(uptime | sed 's/.*load/load/'))" >&2
    measure "$calib" inspect "$log" --json >> "$work/read.txt"
    measure "$calib" csrr "$log" -o "$work/out-$n" >> "$work/csrr.txt"
  done
  col() { cut -d' ' -f"$2" "$1"; }
  read_s=$(col "$work/read.txt" 1 | median)
  read_cpu=$(col "$work/read.txt" 2 | median)
  csrr_s=$(col "$work/csrr.txt" 1 | median)
  csrr_cpu=$(col "$work/csrr.txt" 2 | median)
  ratio() { awk -v a="$1" -v b="$2" 'BEGIN{printf "%.2f", b / a}'; }
  peak() { printf '%s/%s/%s' "$(mb "$(col "$1" 3 | max)")" \
    "$(mb "$(col "$1" 4 | max)")" "$(mb "$(col "$1" 5 | max)")"; }
  printf '%-9s %7s  %-16s %-16s %-12s  %-26s %-26s\n' "$n" \
    "$(mb $(($(stat -c %s "$log") / 1024)))" "$read_s/$read_cpu" "$csrr_s/$csrr_cpu" \
    "$(ratio "$read_s" "$csrr_s")/$(ratio "$read_cpu" "$csrr_cpu")" \
    "$(peak "$work/read.txt")" "$(peak "$work/csrr.txt")"
done
echo "# load after: $(uptime | sed 's/.*load/load/')"
