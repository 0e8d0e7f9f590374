#!/bin/bash
# The discrepancy workflow on the real WPI recordings (../shared/data/external/wpi-dvrk-dynamics):
# identify the PSM on the no-weight insertion-payload recording, analyse the four weighted ones
# with it (no tracking replay), and WPI `two` with the model identified on `one`. Reports and
# stdout per recording in OUTDIR; compare two binaries' OUTDIRs to see what a change moved.
# Usage: scripts/real_recordings.sh BIN OUTDIR   (about 5 minutes on 2 cores)
set -u
B=$(realpath "$1"); O=$2
X=$(realpath "$(dirname "$0")/../../shared/data/external/wpi-dvrk-dynamics")
mkdir -p "$O"; cd "$O"
W=$X/insertion-payload
"$B" identify --recording "$W/one_no_weight_results.csv" --format wpi-csv --model psm -o base.toml > /dev/null 2>&1
for f in "$W"/*.csv; do n=$(basename "$f" .csv); [ "$n" = one_no_weight_results ] && continue
  "$B" discrepancy --model base.toml --recording "$f" --format wpi-csv --report "$n.json" --no-tracking > "$n.out" 2>&1; done
"$B" identify --recording "$X/psm_one_results.csv" --format wpi-csv --model psm -o one.toml > /dev/null 2>&1
"$B" discrepancy --model one.toml --recording "$X/psm_two_results.csv" --format wpi-csv --report two.json > two.out 2>&1
echo done
