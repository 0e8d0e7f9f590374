#!/usr/bin/env bash
# Time and peak memory of `dvrk identify` and `dvrk discrepancy --no-tracking` against the
# recording's length, on one core (docs/recordings.md, "Long recordings"; issue 45).
#
#   bash scripts/long_recordings.sh [path/to/dvrk] [work dir]
#
# Writes synthetic PSM recordings at 1 kHz (6 s, 10 s, 60 s, 5 min: `dvrk synth hidden-effect
# --effect none`) into the work dir (default /tmp/dvrk-long), then prints one line per run:
# elapsed time and maximum resident size (`/usr/bin/time -v`, `taskset -c 0`). With ../shared it
# also times the WPI recordings (6,000 samples at 200 Hz).
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
BIN="$(realpath "${1:-$HERE/target/release/dvrk}")"
WORK="${2:-/tmp/dvrk-long}"
WPI="$HERE/../shared/data/external/wpi-dvrk-dynamics/insertion-payload"
mkdir -p "$WORK" && cd "$WORK"
measure() {
  /usr/bin/time -v taskset -c 0 "$@" 2>&1 >/dev/null |
    awk -F': ' '/Elapsed \(wall/{t=$2} /Maximum resident/{r=$2} END{printf "%s, %.0f MB\n", t, r/1024}'
}
for D in 6 10 60 300; do
  [ -f "r$D.mcap" ] || "$BIN" synth hidden-effect --effect none --seed 3 --duration "$D" -o "r$D.mcap" --answer "a$D.json" >/dev/null
  echo "identify, $((D * 1000)) samples: $(measure "$BIN" identify --recording "r$D.mcap" --model psm -o "id$D.toml")"
  # The analysis needs 7.5 s.
  if [ "$D" -ge 10 ]; then
    echo "discrepancy --no-tracking, $((D * 1000)) samples: $(measure "$BIN" discrepancy --model psm --recording "r$D.mcap" --no-tracking --report "d$D.json")"
  fi
done
if [ -d "$WPI" ]; then
  echo "identify, WPI one_no_weight: $(measure "$BIN" identify --recording "$WPI/one_no_weight_results.csv" --format wpi-csv --model psm -o wpi-base.toml)"
  echo "discrepancy --no-tracking, WPI 205 g: $(measure "$BIN" discrepancy --model wpi-base.toml --recording "$WPI/one_results_1.0_scale_205_grams_insertion.csv" --format wpi-csv --report wpi205.json --no-tracking)"
fi
