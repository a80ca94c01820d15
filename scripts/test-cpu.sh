#!/usr/bin/env bash
# CPU seconds (user + sys) of the README's test command, per test binary, and each test's
# wall time: CPU time does not depend on the load of a shared machine, wall time does.
#
#   bash scripts/test-cpu.sh [OUTDIR]      (default target/test-cpu)
#
# Builds the test targets first (`cargo test --workspace --no-run`, its CPU printed), then runs
# every test binary as `cargo test` would (from its package's directory, the ignored tests
# left out) under /usr/bin/time, with libtest's per-test times (--report-time, accepted by
# stable libtest under RUSTC_BOOTSTRAP=1). Doctests: `cargo test --workspace --doc` (their
# compilation included). Writes OUTDIR/<binary>.log (per-test times) and prints a table.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out=${1:-target/test-cpu}
mkdir -p "$out"
out=$(cd "$out" && pwd)
cpu() { tail -n 1 "$1" | awk '{printf "%7.1f  %7.1f", $1 + $2, $3}'; }

/usr/bin/time -f "%U %S %e" -o "$out/build.time" cargo test --workspace --no-run -q
cargo test --workspace --no-run --message-format=json -q 2>/dev/null | python3 -c '
import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m["profile"]["test"] and m.get("executable"):
        pkg = m["manifest_path"].rsplit("/", 2)[-2]
        kind = m["target"]["kind"][0]
        print(f"{pkg}:{kind}:{m['"'"'target'"'"']['"'"'name'"'"']}\t{m['"'"'executable'"'"']}\t{m['"'"'manifest_path'"'"']}")
' > "$out/bins.tsv"
printf '%-40s %7s  %7s\n' "test binary" "CPU s" "wall s"
printf '%-40s %s\n' "build (cargo test --workspace --no-run)" "$(cpu "$out/build.time")"
while IFS=$'\t' read -r name exe manifest; do
    tag=${name//[:\/]/_}
    (cd "$(dirname "$manifest")" && RUSTC_BOOTSTRAP=1 /usr/bin/time -f "%U %S %e" -o "$out/$tag.time" \
        "$exe" -Z unstable-options --report-time >"$out/$tag.log" 2>&1) || echo "$name FAILED (see $out/$tag.log)"
    printf '%-40s %s\n' "$name" "$(cpu "$out/$tag.time")"
done < "$out/bins.tsv"
/usr/bin/time -f "%U %S %e" -o "$out/doc.time" cargo test --workspace --doc -q >/dev/null 2>&1 || true
printf '%-40s %s\n' "doctests (cargo test --workspace --doc)" "$(cpu "$out/doc.time")"
