#!/usr/bin/env bash
# CPU seconds (user + sys) of each test of one test binary, every test run alone:
#
#   bash scripts/test-cpu-each.sh BINARY PACKAGE_DIR OUTDIR [PARALLEL]
#
# e.g. `bash scripts/test-cpu-each.sh target/debug/deps/cli-<hash> xtask target/test-cpu/cli 2`
# (the binary's path is printed by `cargo test -p xtask --test cli --no-run`). Runs every
# test the README's command runs (ignored ones left out) as its own process,
# `BINARY --exact NAME --test-threads 1` from PACKAGE_DIR (as `cargo test` does), under
# /usr/bin/time: the processes a test spawns (xtask, cc, cargo) are counted, and the
# machine's load does not change the figure as it changes wall time. A test that reads a
# fixture shared through a `OnceLock` pays the whole fixture here, once per test; in one
# `cargo test` process it is computed once. Writes OUTDIR/sorted.txt ("CPU s, wall s, exit
# code, test", slowest first) and each test's output in OUTDIR/t_*.log. PARALLEL (default 1)
# tests at a time: tests that share a scratch directory can fail when run side by side
# (their exit code says so); rerun those alone.
set -euo pipefail
exe=$(realpath "$1")
pkg=$2
out=$3
par=${4:-1}
mkdir -p "$out"
out=$(cd "$out" && pwd)
cd "$pkg"
"$exe" --list --format terse 2>/dev/null | sed -n 's/: test$//p' | sort >"$out/all.txt"
"$exe" --list --ignored --format terse 2>/dev/null | sed -n 's/: test$//p' | sort >"$out/ignored.txt"
comm -23 "$out/all.txt" "$out/ignored.txt" >"$out/run.txt"
: >"$out/results.txt"
export exe out
xargs -P "$par" -I{} bash -c '
    n="{}"
    f="$out/t_$(printf %s "$n" | tr "/:" "__")"
    rc=0
    /usr/bin/time -f "%U %S %e" -o "$f.time" "$exe" --exact "$n" --test-threads 1 >"$f.log" 2>&1 || rc=$?
    printf "%s %s %s\n" "$(tail -n 1 "$f.time" | awk "{printf \"%.1f %.1f\", \$1 + \$2, \$3}")" "$rc" "$n" >>"$out/results.txt"
' <"$out/run.txt"
sort -rn "$out/results.txt" >"$out/sorted.txt"
awk '{c += $1} END {printf "%d tests, %.1f CPU s (each alone)\n", NR, c}' "$out/sorted.txt"
head -n 20 "$out/sorted.txt"
