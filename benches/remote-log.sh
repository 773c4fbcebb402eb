#!/usr/bin/env bash
# A log read from object storage: `calib csrr s3://…` against downloading the object with the
# endpoint's own client and calibrating the copy from disk, on a local S3 endpoint (moto's
# server), with the bytes calib fetched.
#
#   benches/remote-log.sh                     # 1e7 samples
#   benches/remote-log.sh 1000000             # another size
#   CALIB=target/debug/calib benches/remote-log.sh   # a calib already built (default: release)
#   KEEP=/tmp/big benches/remote-log.sh       # keep the log (and reuse it on the next run)
#
# Needs `moto_server` on PATH (`pip install 'moto[server]'`); boto3, moto's own dependency, is
# the "endpoint's own client" (no aws CLI here). The log is the JointState MCAP that
# benches/large-log.sh simulates (csrr72.toml at 10 kHz, the revolutions chosen for ~N samples).
# Each of (a) and (b) runs once per repetition, alternating; medians of REPEAT (default 3).
#   (a) remote:   calib csrr s3://bench/run.mcap -o OUT
#   (b) download: python -c 'boto3…download_file' then calib csrr run.mcap -o OUT
# The maps of (a) and (b) must be byte-identical. moto keeps objects in its process's memory
# and serves them from Python: it is slower than a real store; both paths pay that.
set -euo pipefail

cd "$(dirname "$0")/.."
n=${1:-10000000}
repeat=${REPEAT:-3}
calib=${CALIB:-}
if [[ -z $calib ]]; then
  cargo build --release -p calib-cli >&2
  calib="$PWD/target/release/calib"
fi
server=$(command -v moto_server) || { echo "moto_server is not on PATH" >&2; exit 1; }
python=$(dirname "$server")/python
if [[ -n ${KEEP:-} ]]; then
  work=$KEEP
  mkdir -p "$work"
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi

revolutions=$(awk -v n="$n" 'BEGIN{printf "%d", (n / 10000 - 28) * 60 / 60 / 5 + 0.5}')
scenario="$work/run-$n.toml"
log="$work/run-$n.mcap"
sed -e "/^rate_hz/s/.*/rate_hz = 10000.0/" -e "/^speed_rpm/s/.*/speed_rpm = 60.0/" \
  -e "/^revolutions/s/.*/revolutions = $revolutions.0/" \
  testdata/scenarios/csrr72.toml > "$scenario"
if [[ ! -s $log ]] || ! cmp -s "$scenario" "$log.toml"; then
  echo "simulating $n samples → $log" >&2
  "$calib" simulate "$scenario" -o "$log" >&2
  cp "$scenario" "$log.toml"
fi

port=$("$python" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
"$server" -H 127.0.0.1 -p "$port" > "$work/moto.log" 2>&1 &
moto=$!
trap 'kill $moto 2>/dev/null; [[ -n ${KEEP:-} ]] || rm -rf "$work"' EXIT
export AWS_ENDPOINT_URL="http://127.0.0.1:$port" AWS_ALLOW_HTTP=true AWS_REGION=us-east-1 \
  AWS_ACCESS_KEY_ID=testing AWS_SECRET_ACCESS_KEY=testing
until "$python" -c "import socket; socket.create_connection(('127.0.0.1', $port), 1)" 2>/dev/null; do
  sleep 0.2
done
"$python" - "$log" <<'EOF'
import sys, boto3
s3 = boto3.client("s3")
s3.create_bucket(Bucket="bench")
s3.upload_file(sys.argv[1], "bench", "run.mcap")
EOF

# Prints "wall_s cpu_s" of "$@" (standard output to /dev/null, standard error to $work/err).
measure() {
  /usr/bin/time -f '%e %U %S' -o "$work/time.txt" "$@" > /dev/null 2> "$work/err"
  awk '{printf "%.2f %.2f\n", $1, $2 + $3}' "$work/time.txt"
}
median() { sort -n | awk '{a[NR]=$1} END{print a[int((NR+1)/2)]}'; }

: > "$work/a.txt"; : > "$work/dl.txt"; : > "$work/b.txt"
for _ in $(seq "$repeat"); do
  rm -rf "$work/out-a" "$work/out-b" "$work/copy.mcap"
  measure "$calib" csrr s3://bench/run.mcap -o "$work/out-a" >> "$work/a.txt"
  note=$(grep 'fetched' "$work/err" || true)
  measure "$python" -c "import boto3; boto3.client('s3').download_file('bench', 'run.mcap', '$work/copy.mcap')" >> "$work/dl.txt"
  measure "$calib" csrr "$work/copy.mcap" -o "$work/out-b" >> "$work/b.txt"
  cmp "$work/out-a/a.csv" "$work/out-b/a.csv"
  cmp "$work/out-a/b.csv" "$work/out-b/b.csv"
done

size=$(stat -c %s "$log")
printf '# %s, %s cores, calib %s, %d samples, log %d bytes, %d runs each\n' \
  "$(date -u +%Y-%m-%dT%H:%MZ)" "$(nproc)" "$calib" "$n" "$size" "$repeat"
printf '# %s\n' "$note"
printf '%-34s %8s %8s\n' "" "wall s" "cpu s"
printf '%-34s %8s %8s\n' "(a) calib csrr s3://…" \
  "$(cut -d' ' -f1 "$work/a.txt" | median)" "$(cut -d' ' -f2 "$work/a.txt" | median)"
printf '%-34s %8s %8s\n' "(b1) boto3 download_file" \
  "$(cut -d' ' -f1 "$work/dl.txt" | median)" "$(cut -d' ' -f2 "$work/dl.txt" | median)"
printf '%-34s %8s %8s\n' "(b2) calib csrr on the copy" \
  "$(cut -d' ' -f1 "$work/b.txt" | median)" "$(cut -d' ' -f2 "$work/b.txt" | median)"
printf '# load after: %s\n' "$(uptime | sed 's/.*load/load/')"
