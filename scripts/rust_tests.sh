#!/usr/bin/env bash
# Every Rust test of the workspace (what `cargo test --release --workspace` runs), in two streams
# so that neither waits for the other: scripts/test.sh runs this beside the Python tests.
# - dvrk-calib's `calib` binary, the longest (about 150 s on 2 cores), starts as soon as it is
#   built, in two processes: its `payload_real` module (the WPI insertion recordings: five tests,
#   68 CPU-s, one of them 38 s) beside the rest. libtest starts a binary's tests in name order,
#   and in one process that 38 s test, among the last to start, ran on by itself for 27 s at
#   the end while the other core had nothing left to do;
# - meanwhile the rest of the build (the other harnesses, the examples; cargo's build lock puts
#   it after the first one's), then every other test executable cargo lists, each from its
#   package's directory as `cargo test` runs it, then the doc tests.
# Each stream's output is printed when both have ended. Usage: bash scripts/rust_tests.sh PYTHON
set -uo pipefail
cd "$(dirname "$0")/.."
py="${1:-python3}"

out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
cargo test --release --workspace --test calib -- --skip payload_real > "$out/calib" 2>&1 &
calib=$!

# After the first stream's build, which then runs while this one builds (cargo's own lines:
# a dependency's name may hold `error`, as thiserror's does).
until grep -qE "^ +Running|^error" "$out/calib" || ! kill -0 "$calib" 2> /dev/null; do
    sleep 1
done
# The same binary, now built, for the module the other process skips.
cargo test --release --workspace --test calib -- payload_real > "$out/payload_real" 2>&1 &
payload_real=$!
status=0
if cargo test --release --workspace --no-run --message-format=json-render-diagnostics > "$out/targets.json"; then
    # One line per test executable: its package's directory, the executable, its source.
    "$py" - "$out/targets.json" > "$out/targets.tsv" <<'EOF' || status=$?
import json, os, sys
for line in open(sys.argv[1]):
    m = json.loads(line)
    if m.get("reason") != "compiler-artifact" or not m.get("executable") or not m["profile"]["test"]:
        continue
    t = m["target"]
    if t["name"] == "calib" and t["kind"] == ["test"]:
        continue  # the other stream's
    print(os.path.dirname(m["manifest_path"]), m["executable"], t["src_path"], sep="\t")
EOF
    while IFS=$'\t' read -r dir exe src; do
        echo "     Running $src ($exe)"
        (cd "$dir" && "$exe") || status=$?
    done < "$out/targets.tsv"
    # Not the benchmarks' package: its library is empty (`doctest = false`, which `--doc` does
    # not heed), and its doc test alone would build criterion (11 s of a clean-clone run). Its
    # exclusion leaves every other package's features as they are (the same compiled libraries,
    # checked with --message-format=json).
    cargo test --release --workspace --exclude dvrk-benches --doc || status=$?
else
    status=1
fi
wait "$calib" || status=$?
wait "$payload_real" || status=$?
echo "=== dvrk-calib calib (all but payload_real)"
cat "$out/calib"
echo "=== dvrk-calib calib payload_real"
cat "$out/payload_real"
exit "$status"
