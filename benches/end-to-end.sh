#!/usr/bin/env bash
# calib's commands against the floor, on one large JointState MCAP from each writer, and on a
# rosbag2 SQLite bag, in one run.
#
#   benches/end-to-end.sh                    # 10 M samples, 5 runs of each
#   SAMPLES=2000000 REPEAT=3 benches/end-to-end.sh
#   KEEP=/tmp/e2e benches/end-to-end.sh      # keep the logs (and reuse them next time)
#   CALIB=/path/to/other/calib benches/end-to-end.sh   # measure another build beside the floor
#   CALIB=.../calib FLOOR=.../mcap_floor benches/end-to-end.sh   # builds nothing
#   WRITERS=python BAG_SAMPLES=0 COAST_HZ=0 benches/end-to-end.sh   # the Python writer's log only
#   WRITERS= COAST_HZ=0 benches/end-to-end.sh   # the bag only
#   SPEED_RPM=190 benches/end-to-end.sh      # 3,158 samples per revolution (default 60: 10,000)
#
# The log: two 72-pole-pair sensors and a reference as in testdata/scenarios/csrr72.toml,
# 5 CSRR sessions at 60 r/min sampled at 10 kHz, as ROS 2 JointState messages (joints a, b,
# ref) on /joint_states in zstd chunks, written by each writer of WRITERS (default both; empty:
# none):
#   calib      `calib simulate` (the mcap crate's Writer: zstd chunks of its default size,
#              header stamps and log times the simulated times, from 0)
#   python     benches/gen_python_mcap.py: the official Python `mcap` writer (its defaults: zstd
#              chunks of 1 MiB) from the CSV `calib simulate` writes of the same scenario — the
#              same samples, schema text and channel metadata as rosbag2 records them, stamps
#              from 2023-11-14 (the simulated times + 1,700,000,000 s), log and publish times
#              the receive times 200–250 µs later, sequence 0
# The Python generators run in a virtual environment, VENV (default WORK/venv, made with
# `python3 -m venv` and `pip install mcap numpy` when it lacks them).
# The floor: FLOOR (default `mcap_floor`, crates/calib-io/examples/mcap_floor.rs, built here) —
# the mcap crate's MessageStream over the memory-mapped file plus the least decode of each
# JointState's positions, one thread. Then, on each writer's log, alternating with it REPEAT
# times each, printing one table per writer:
#   inspect    calib inspect LOG --json
#   inspect-j1 calib inspect LOG --json --jobs 1   (one thread: the reading and the rest)
#   csrr       calib csrr LOG -o OUT -q
#   csrr-j1    calib csrr LOG -o OUT -q --jobs 1
#   reference  calib reference LOG --dut b --ref ref -o OUT -q
#   apply      calib apply OUT/a.csv LOG --channel a -o LOG2   (reads, corrects, re-compresses),
#              beside floor+write: `mcap_floor LOG --write COPY`, the floor plus every message
#              written unchanged into a new MCAP through the mcap crate's Writer (the input's
#              zstd, default chunk size and level, one thread) — the floor of a rewriter
# With both writers, csrr's maps on the two logs are compared (benches/compare_tables.py: the
# largest difference of error_arcsec and u_arcsec, against a quarter of the smallest u).
# Then a rosbag2 bag (benches/gen_rosbag_db3.py: a folder with metadata.yaml and one .db3 file,
# the tables rosbag2's sqlite3 storage writes, the Python writer's messages) of BAG_SAMPLES
# samples of the same scenario (default 1,000,000: 980,001 messages; 0 leaves the bag out), and
# alternating REPEAT times each:
#   bag-floor  BAG_FLOOR, a shell command run by bash with $DB3 the .db3 file (and $BAG the bag
#              folder, $VENV the environment); default `bag_floor` beside the MCAP floor
#              (crates/calib-io/examples/bag_floor.rs): one rusqlite scan of the messages in the
#              order a bag is replayed (ORDER BY timestamp, id, through rosbag2's timestamp
#              index), each payload borrowed from SQLite and its JointState positions decoded as
#              mcap_floor decodes them, one thread. Where that binary is missing (FLOOR given
#              without it), the sqlite3 command-line tool (installed with apt-get when missing)
#              scanning the same rows without decoding them:
#              sqlite3 -readonly "$DB3" 'SELECT count(*), total(timestamp), sum(length(data))
#                FROM (SELECT timestamp, data FROM messages ORDER BY timestamp, id)';
#              BAG_FLOOR='"$VENV"/bin/python benches/db3_floor.py "$DB3"' is a Python sqlite3
#              scan that also decodes every position with numpy.frombuffer (slower: Python's cost
#              per row)
#   sqlite-scan the sqlite3 tool's plain scan of the messages table (issue 51's bar for inspect):
#              sqlite3 -readonly "$DB3" 'SELECT count(*), sum(length(data)) FROM messages'
#   inspect    calib inspect BAG --json
#   csrr       calib csrr BAG -o OUT -q   (its maps compared with calib csrr on the bag's CSV)
# Then on a last log, a coast for `calib tdr`: testdata/scenarios/spindown.toml (an air-bearing
# spin-down from 600 r/min, two channels) recorded for COAST_S s at COAST_HZ (default 100 s at
# 100 kHz: 10,000,001 samples, 600 → 80 r/min) by calib, the floor on it alternating REPEAT
# times with
#   tdr        calib tdr COAST --channel enc -o OUT -q
# and, in the same rounds, the floor and `calib csrr` on the first writer's log again
# (floor-paired, csrr-paired), so that tdr's ratio and csrr's come from the same minutes.
# (COAST_HZ=0 leaves it out: a tdr run takes minutes, the fit and not the reading.)
# It prints each one's median wall and CPU time, its peak RSS, and the ratios of its median wall
# and CPU time to the floor's (apply's: to floor+write's; the bag's: to bag-floor's, then to
# sqlite-scan's). Each log is read
# from the page cache (a first, unmeasured read warms it). Logs are made again only when their
# scenario or generator changed.
set -euo pipefail

cd "$(dirname "$0")/.."
samples=${SAMPLES:-10000000}
repeat=${REPEAT:-5}
rate_hz=10000
speed_rpm=${SPEED_RPM:-60}

if [[ ! -x /usr/bin/time ]]; then
  echo "installing GNU time (apt-get install time)" >&2
  apt-get install -y time >&2
fi

writers=${WRITERS-calib python}
bag_samples=${BAG_SAMPLES:-1000000}
for writer in $writers; do
  case $writer in
    calib | python) ;;
    *) echo "WRITERS: unknown writer \`$writer\`; give calib, python or both" >&2; exit 2 ;;
  esac
done
if [[ -z ${FLOOR:-} ]]; then
  cargo build --release --locked -p calib-io --example mcap_floor --example bag_floor >&2
fi
floor=${FLOOR:-$PWD/target/release/examples/mcap_floor}
rusqlite_floor="$(dirname "$floor")/bag_floor"
if [[ -z ${BAG_FLOOR:-} && $bag_samples != 0 && ! -x $rusqlite_floor ]] \
  && ! command -v sqlite3 > /dev/null; then
  echo "installing the sqlite3 command-line tool (apt-get install sqlite3)" >&2
  apt-get install -y sqlite3 >&2
fi

if [[ -z ${CALIB:-} ]]; then
  cargo build --release --locked -p calib-cli >&2
fi
calib=${CALIB:-$PWD/target/release/calib}
build="calib $(git rev-parse --short HEAD)"
[[ -n ${CALIB:-} ]] && build="calib $CALIB"
if [[ -n ${KEEP:-} ]]; then
  work=$KEEP
  mkdir -p "$work"
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi
export VENV=${VENV:-$work/venv}
# The Python generators' environment: made once, kept in WORK (or VENV).
python_env() {
  if ! "$VENV/bin/python" -c 'import mcap, numpy' 2> /dev/null; then
    echo "making $VENV (python3 -m venv; pip install mcap numpy)" >&2
    python3 -m venv "$VENV" >&2
    "$VENV/bin/pip" install --quiet mcap numpy >&2
  fi
}

# Writes the csrr72 scenario for SAMPLES samples into FILE.
# Per session: ramps of 1 s, a 1 s pause; 4 relative turns of 2 s; 28 s besides the revolutions.
csrr_scenario() {
  local revolutions
  revolutions=$(awk -v n="$1" -v r="$rate_hz" -v s="$speed_rpm" \
    'BEGIN{printf "%d", (n / r - 28) * s / 60 / 5 + 0.5}')
  sed -e "/^rate_hz/s/.*/rate_hz = $rate_hz.0/" -e "/^speed_rpm/s/.*/speed_rpm = $speed_rpm.0/" \
    -e "/^revolutions/s/.*/revolutions = $revolutions.0/" \
    testdata/scenarios/csrr72.toml > "$2"
}
# Simulates SCENARIO into LOG unless LOG was made from the same scenario (kept in LOG.toml).
simulate_once() {
  if [[ ! -s $2 ]] || ! cmp -s "$1" "$2.toml"; then
    echo "simulating $1 → $2" >&2
    "$calib" simulate "$1" -o "$2" -q >&2
    cp "$1" "$2.toml"
  fi
}
# Whether OUT is missing or older than any of the files after it.
stale() {
  local out=$1 f
  shift
  [[ -e $out ]] || return 0
  for f in "$@"; do [[ $f -nt $out ]] && return 0; done
  return 1
}
scenario="$work/run.toml"
csrr_scenario "$samples" "$scenario"
# The log of each writer.
declare -A logs
for writer in $writers; do
  case $writer in
    calib)
      logs[calib]="$work/run.mcap"
      simulate_once "$scenario" "${logs[calib]}"
      ;;
    python)
      logs[python]="$work/run-python.mcap"
      simulate_once "$scenario" "$work/run.csv"
      if stale "${logs[python]}" "$work/run.csv" benches/gen_python_mcap.py benches/joint_states.py; then
        python_env
        "$VENV/bin/python" benches/gen_python_mcap.py "$work/run.csv" "${logs[python]}"
      fi
      ;;
  esac
done

# One line: wall_s cpu_s max_rss_kb.
measure() {
  /usr/bin/time -f '%e %U %S %M' -o "$work/time.txt" "$@" > /dev/null
  awk '{printf "%.3f %.3f %d\n", $1, $2 + $3, $4}' "$work/time.txt"
}
median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

names=(floor inspect inspect-j1 csrr csrr-j1 reference floor+write apply)
run() {
  case $1 in
    floor) measure "$floor" "$log" ;;
    inspect) measure "$calib" inspect "$log" --json ;;
    inspect-j1) measure "$calib" inspect "$log" --json --jobs 1 ;;
    csrr) measure "$calib" csrr "$log" -o "$work/out-csrr-$writer" -q ;;
    csrr-j1) measure "$calib" csrr "$log" -o "$work/out-csrr-j1-$writer" -q --jobs 1 ;;
    reference) measure "$calib" reference "$log" --dut b --ref ref -o "$work/out-ref-$writer" -q ;;
    floor+write) rm -f "$work/floor-copy.mcap"
      measure "$floor" "$log" --write "$work/floor-copy.mcap" ;;
    apply) rm -f "$work/applied.mcap"
      measure "$calib" apply "$work/table-$writer/a.csv" "$log" --channel a \
        -o "$work/applied.mcap" -q ;;
  esac
}
# Prints one line per name: its median wall and CPU time, peak RSS, wall ÷ BASE's wall and
# CPU ÷ BASE's CPU, from WORK/NAME.txt (apply's ratios are to floor+write's).
table() {
  local base=$1 name wall cpu rss f fc
  shift
  printf '%-12s %10s %10s %10s %9s %9s\n' command "wall s" "cpu s" "peak MB" "÷ floor" "cpu ÷"
  for name in "$@"; do
    wall=$(cut -d' ' -f1 "$work/$name.txt" | median)
    cpu=$(cut -d' ' -f2 "$work/$name.txt" | median)
    rss=$(cut -d' ' -f3 "$work/$name.txt" | sort -g | tail -1)
    f=$(cut -d' ' -f1 "$work/$base.txt" | median)
    fc=$(cut -d' ' -f2 "$work/$base.txt" | median)
    if [[ $name == apply ]]; then
      f=$(cut -d' ' -f1 "$work/floor+write.txt" | median)
      fc=$(cut -d' ' -f2 "$work/floor+write.txt" | median)
    fi
    awk -v n="$name" -v w="$wall" -v c="$cpu" -v r="$rss" -v f="$f" -v fc="$fc" \
      'BEGIN{printf "%-12s %10.2f %10.2f %10.0f %9.2f %9.2f\n", n, w, c, r / 1024, w / f, c / fc}'
  done
}
size_mb() { du -sb "$1" | awk '{printf "%.0f MB", $1 / 1e6}'; }
for writer in $writers; do
  log=${logs[$writer]}
  "$floor" "$log" >&2
  "$calib" csrr "$log" -o "$work/table-$writer" -q > /dev/null
  for name in "${names[@]}"; do : > "$work/$name.txt"; done
  for ((i = 1; i <= repeat; i++)); do
    echo "$writer round $i/$repeat ($(uptime | sed 's/.*load/load/'))" >&2
    for name in "${names[@]}"; do run "$name" >> "$work/$name.txt"; done
  done
  echo "# $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores, $build, writer $writer: $(basename "$log"), $(size_mb "$log"), $repeat runs each"
  table floor "${names[@]}"
  echo "# load after: $(uptime | sed 's/.*load/load/')"
done
if [[ -n ${logs[calib]:-} && -n ${logs[python]:-} ]]; then
  echo "# csrr's maps, calib's log against the Python writer's (compare_tables.py):"
  python3 benches/compare_tables.py "$work/out-csrr-calib" "$work/out-csrr-python" a.csv b.csv ||
    echo "# the maps differ beyond u/4: a writer's log is not read as the other's" >&2
fi

# The bag, and calib on it against a bare SQLite scan.
if [[ $bag_samples != 0 ]]; then
  bag_scenario="$work/bag.toml"
  csrr_scenario "$bag_samples" "$bag_scenario"
  simulate_once "$bag_scenario" "$work/bag.csv"
  export BAG="$work/bag" DB3="$work/bag/bag_0.db3"
  if stale "$DB3" "$work/bag.csv" benches/gen_rosbag_db3.py benches/joint_states.py; then
    python_env
    rm -rf "$BAG"
    "$VENV/bin/python" benches/gen_rosbag_db3.py "$work/bag.csv" "$BAG"
  fi
  if [[ -n ${BAG_FLOOR:-} ]]; then
    bag_floor=$BAG_FLOOR
    bag_floor_name=$BAG_FLOOR
  elif [[ -x $rusqlite_floor ]]; then
    bag_floor="\"$rusqlite_floor\" \"\$DB3\""
    bag_floor_name="bag_floor: rusqlite ordered scan + JointState decode"
  else
    bag_floor='sqlite3 -readonly "$DB3" "SELECT count(*), total(timestamp),
      sum(length(data)) FROM (SELECT timestamp, data FROM messages ORDER BY timestamp, id)"'
    bag_floor_name="sqlite3 ordered scan, nothing decoded"
  fi
  bash -c "$bag_floor" >&2
  # The issue's bar for the bag: the sqlite3 tool's plain scan of the messages table, in the
  # table's own order, nothing decoded and no payload read (`length` of a blob is in its header).
  sqlite_scan='sqlite3 -readonly "$DB3" "SELECT count(*), sum(length(data)) FROM messages"'
  command -v sqlite3 > /dev/null || sqlite_scan=
  : > "$work/bag-floor.txt"
  : > "$work/sqlite-scan.txt"
  : > "$work/inspect.txt"
  : > "$work/csrr.txt"
  for ((i = 1; i <= repeat; i++)); do
    echo "bag round $i/$repeat ($(uptime | sed 's/.*load/load/'))" >&2
    measure bash -c "$bag_floor" >> "$work/bag-floor.txt"
    [[ -n $sqlite_scan ]] && measure bash -c "$sqlite_scan" >> "$work/sqlite-scan.txt"
    measure "$calib" inspect "$BAG" --json >> "$work/inspect.txt"
    measure "$calib" csrr "$BAG" -o "$work/out-csrr-bag" -q >> "$work/csrr.txt"
  done
  echo "# $(date -u +%Y-%m-%dT%H:%MZ), rosbag2 bag (sqlite3): $(basename "$DB3"), $(sqlite3 "$DB3" 'SELECT count(*) FROM messages' 2> /dev/null || echo "$bag_samples") messages, $(size_mb "$BAG"), $repeat runs each"
  echo "# bag-floor: $bag_floor_name"
  table bag-floor bag-floor inspect csrr
  if [[ -n $sqlite_scan ]]; then
    echo "# against the sqlite3 tool's plain scan (SELECT count(*), sum(length(data)) FROM messages):"
    table sqlite-scan sqlite-scan inspect csrr
  fi
  echo "# load after: $(uptime | sed 's/.*load/load/')"
  "$calib" csrr "$work/bag.csv" -o "$work/out-csrr-bag-csv" -q > /dev/null
  echo "# csrr's maps, the bag against its CSV (compare_tables.py):"
  python3 benches/compare_tables.py "$work/out-csrr-bag-csv" "$work/out-csrr-bag" a.csv b.csv ||
    echo "# the maps differ beyond u/4: the bag is not read as its CSV" >&2
fi

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
  # csrr on the first writer's log in the same rounds: the bar "tdr at or below csrr's ratio"
  # compares two ratios measured minutes apart otherwise, and the machine drifts by as much.
  paired=${logs[${writers%% *}]:-}
  for name in floor-coast tdr floor-paired csrr-paired; do : > "$work/$name.txt"; done
  for ((i = 1; i <= repeat; i++)); do
    echo "coast round $i/$repeat ($(uptime | sed 's/.*load/load/'))" >&2
    measure "$floor" "$coast" >> "$work/floor-coast.txt"
    measure "$calib" tdr "$coast" --channel enc -o "$work/out-tdr" -q >> "$work/tdr.txt"
    if [[ -n $paired ]]; then
      measure "$floor" "$paired" >> "$work/floor-paired.txt"
      measure "$calib" csrr "$paired" -o "$work/out-csrr-paired" -q >> "$work/csrr-paired.txt"
    fi
  done
  echo "# $(size_mb "$coast") coast log, $repeat runs each"
  table floor-coast floor-coast tdr
  if [[ -n $paired ]]; then
    echo "# in the same rounds, $(basename "$paired") (tdr's bar: its ratio at or below csrr's):"
    table floor-paired floor-paired csrr-paired
  fi
  echo "# load after: $(uptime | sed 's/.*load/load/')"
fi
