#!/usr/bin/env bash
# The exported estimator on the Cortex-M instruction set (docs/embedded.md):
#
#   for each shipped scenario (the certified preset, the cart-pendulum):
#   1. `cargo xtask reproduce` on the portable kernel (QP_ITER_KERNEL=portable) → trace.csv;
#   2. `cargo xtask export --lang c` for the scenario's method at the K that trace.csv ran;
#   3. the replay built with the host's cc: x̂ equals trace.csv's xhat columns bit for bit;
#   4. the replay built with Debian's arm-none-eabi-gcc for Cortex-M4F (mps2-an386) and
#      Cortex-M7 (mps2-an500), run under qemu-system-arm with semihosting and -icount:
#      the same bits; flash and RAM from arm-none-eabi-size; instructions per MHE step
#      (push + estimate) from SysTick under -icount (instructions, not cycles);
#   5. with the MPC (certified preset): the loop program (estimator + K_c-iteration MPC at
#      the joint certificate's floor) on trace.csv's y, on the host and on both targets:
#      the same bits; flash, RAM and instructions per loop step (push + estimate + control).
#
# Modes: `check` (default: the above), `calibrate` (the instruction model's measurements:
# every method at several sizes and K on both boards → crates/mhe-budget/data/, then the
# MPC's control inside the loop program (CALIB_MHE=0 / CALIB_MPC=0 skip a part), then
# `python3 scripts/fit-instructions.py`), `table` (docs/embedded.md's budget table).
# `calibrate` and `table` are run by hand (wall times in docs/embedded.md), not by CI.
#
# Installs gcc-arm-none-eabi, libnewlib-arm-none-eabi and qemu-system-arm with apt when
# missing. Writes target/cortex-m/summary.md. Exit status non-zero on any mismatch.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

need=()
command -v arm-none-eabi-gcc >/dev/null 2>&1 || need+=(gcc-arm-none-eabi libnewlib-arm-none-eabi)
[ -e /usr/lib/arm-none-eabi/lib/librdimon.a ] || need+=(libnewlib-arm-none-eabi)
command -v qemu-system-arm >/dev/null 2>&1 || need+=(qemu-system-arm)
command -v python3 >/dev/null 2>&1 || need+=(python3)
command -v make >/dev/null 2>&1 || need+=(make)
if [ ${#need[@]} -gt 0 ]; then
    echo "installing ${need[*]} (apt)"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}" >/dev/null
fi
arm-none-eabi-gcc --version | head -1
qemu-system-arm --version | head -1

MODE=${1:-check}
case "$MODE" in
check | calibrate | table) ;;
*)
    echo "usage: bash scripts/cortex-m.sh [check|calibrate|table]" >&2
    exit 2
    ;;
esac
# The export tool: `cargo xtask` unless XTASK names a built binary (a calibration takes
# long enough that a rebuild in between would mix two versions; .ci/run passes the one its
# test command built, so that no other feature set of the workspace is compiled).
read -r -a XTASK_CMD <<<"${XTASK:-cargo xtask}"

OUT=target/cortex-m
[ "$MODE" = check ] && rm -rf "$OUT"
mkdir -p "$OUT"
CALIB_DIR=crates/mhe-budget/data

# Calibration (`calibrate`): the max instructions per step (the full-window step) of every
# exportable method on both targets, at several horizons M (sizes n_z) and K. One export per
# (size, method) at K = 1 (uncertified: the data do not depend on K); the K of each point is
# set in a copy's mhe_data.h (MHE_K) and the self-test is skipped there (its stored bits
# belong to the exported K): the instructions are those of the K-iteration step on the
# exported data. Input: M + 2 rows of a fixed smooth (u, y) sequence, so the last steps run
# the full window. Writes crates/mhe-budget/data/cortex-m-points.csv; the fit is
# scripts/fit-instructions.py.
calib_dims() { # mhe_data.h → "M NZ NTH NX NU NY"
    for key in M NZ NTH NX NU NY; do
        sed -n "s/^#define MHE_$key \([0-9]*\)$/\1/p" "$1"
    done | tr '\n' ' '
}
calibrate() {
    local dir="$OUT/calib"
    mkdir -p "$dir"
    local points="$dir/points.csv"
    # An interrupted calibration resumes: the (scalar, method, size) already in points.csv
    # are kept. A new calibration starts from the stored points (the f64 ones of an older
    # file, without the scalar column, get `f64`), so CALIB_SCALARS=f32 adds f32 only.
    if [ ! -s "$points" ]; then
        if [ -s "$CALIB_DIR/cortex-m-points.csv" ]; then
            grep -v '^#' "$CALIB_DIR/cortex-m-points.csv" |
                awk -F, 'NR == 1 { if ($NF != "scalar") $0 = $0 ",scalar"; print; next }
                         { if (NF == 12) $0 = $0 ",f64"; print }' >"$points"
        else
            echo "target,method,scenario,horizon,n,n_theta,nx,nu,ny,k,mean,max,scalar" >"$points"
        fi
    fi
    local spec file horizon method k tag machine label art kart mean max dims input scalar
    for scalar in ${CALIB_SCALARS:-f64 f32}; do
    for method in ${CALIB_METHODS:-pg admm-pr fista admm pg-jacobi fista-jacobi admm-jacobi admm-pr-jacobi}; do
        for spec in ${CALIB_SIZES:-case-study-certified:3 case-study-certified:9 cart-pendulum:9}; do
            IFS=: read -r file horizon <<<"$spec"
            local scen="$dir/$file-m$horizon.toml"
            # The MHE horizon (in [mhe]); no MPC in the export; no sample_time (an older
            # XTASK binary may not know the key, and the export does not need it).
            awk -v m="$horizon" '/^\[/ { sec = $0 } sec == "[mhe]" && /^horizon *=/ { print "horizon = " m; next }
                sec == "[mpc]" && /^iterations *=/ { next } /^sample_time *=/ { next } { print }' \
                "scenarios/$file.toml" >"$scen"
            if grep -q "^[^,]*,$method,$file,$horizon,.*,$scalar\$" "$points"; then
                echo "==> $file, M = $horizon, $method, $scalar: in $points already"
                continue
            fi
            art="$dir/$file-m$horizon-$method-$scalar"
            echo "==> calibrate $file, M = $horizon, $method, $scalar"
            "${XTASK_CMD[@]}" export --scenario "$scen" --out "$art" --lang c --method "$method" \
                --k 1 --scalar "$scalar" --allow-uncertified >"$art.log" 2>&1 || { cat "$art.log"; exit 1; }
            read -r -a dims <<<"$(calib_dims "$art/mhe_data.h")"
            input="$dir/input-$file-m$horizon.csv"
            # M + 2 rows: u_i = 0.1 sin(t + i), y_j = 0.2 cos(0.7 t + j).
            awk -v rows=$((dims[0] + 2)) -v nu="${dims[4]}" -v ny="${dims[5]}" 'BEGIN {
                for (t = 0; t < rows; t++) { s = "";
                    for (i = 0; i < nu; i++) s = s (s == "" ? "" : ",") sprintf("%.17g", 0.1 * sin(t + i));
                    for (j = 0; j < ny; j++) s = s (s == "" ? "" : ",") sprintf("%.17g", 0.2 * cos(0.7 * t + j));
                    print s } }' >"$input"
            for k in ${CALIB_KS:-1 16 256}; do
                kart="$art-k$k"
                rm -rf "$kart"
                cp -r "$art" "$kart"
                sed -i "s/^#define MHE_K .*/#define MHE_K $k/" "$kart/mhe_data.h"
                # K is the 7th field of the problem (nx, nu, ny, nw1, nw2, M, K, method, …).
                sed -i "/mhe_exported_problem = {/{n;s/^\(    \([0-9]*, \)\{6\}\)[0-9]*,/\1$k,/}" "$kart/mhe_data.c"
                grep -A1 'mhe_exported_problem = {' "$kart/mhe_data.c" | grep -q "^    \([0-9]*, \)\{6\}$k, MHE_" \
                    || { echo "could not set K = $k in $kart/mhe_data.c"; exit 1; }
                sed -i 's|rc = mhe_self_test(&state);|rc = 0; /* calibration: self-test skipped */|' "$kart/replay.c"
                for target in "m4:mps2-an386:cortex-m4f" "m7:mps2-an500:cortex-m7"; do
                    IFS=: read -r tag machine label <<<"$target"
                    make -s -C "$kart" "replay-$tag.elf" DEFS=-DMHE_ALLOW_UNCERTIFIED
                    timeout 1200 qemu-system-arm -M "$machine" -nographic -monitor none -serial none \
                        -semihosting-config enable=on,target=native -icount shift=0 \
                        -kernel "$kart/replay-$tag.elf" <"$input" >"$kart/$tag.out" 2>"$kart/$tag.err"
                    mean=$(sed -n 's/.*mean \([0-9]*\), max \([0-9]*\).*/\1/p' "$kart/$tag.err")
                    max=$(sed -n 's/.*mean \([0-9]*\), max \([0-9]*\).*/\2/p' "$kart/$tag.err")
                    if [ -z "$mean" ] || [ -z "$max" ]; then
                        echo "no instruction count in $kart/$tag.err:"
                        cat "$kart/$tag.err"
                        exit 1
                    fi
                    echo "$label,$method,$file,${dims[0]},${dims[1]},${dims[2]},${dims[3]},${dims[4]},${dims[5]},$k,$mean,$max,$scalar" >>"$points"
                    echo "    $label, $scalar, K = $k: max $max instructions/step"
                done
                rm -rf "$kart"
            done
        done
    done
    done
    mkdir -p "$CALIB_DIR"
    local earlier=""
    [ -s "$CALIB_DIR/cortex-m-points.csv" ] &&
        earlier=$(grep '^# .*calibrate\|^# 20' "$CALIB_DIR/cortex-m-points.csv" | sed 's/^# \(earlier points: \)*/# earlier points: /' | awk '!seen[$0]++')
    {
        echo "# Max (and mean) instructions per MHE step (push + estimate) of the exported C under"
        echo "# qemu-system-arm -icount shift=0 (emulated instructions, not cycles), measured by"
        echo "# \`bash scripts/cortex-m.sh calibrate\` (scalars: ${CALIB_SCALARS:-f64 f32}) at commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown),"
        echo "# $(date -u +%Y-%m-%d), $(arm-none-eabi-gcc --version | head -1), $(qemu-system-arm --version | head -1)."
        [ -n "$earlier" ] && echo "$earlier"
        cat "$points"
    } >"$CALIB_DIR/cortex-m-points.csv"
    echo "wrote $CALIB_DIR/cortex-m-points.csv; fit: python3 scripts/fit-instructions.py"
}
# The MPC's share of a loop step (`calibrate`, after the MHE's points; CALIB_MPC=0 skips
# it): the loop program (MHE at K = 1 + the K_c-iteration MPC) of an export with `--kc 1`
# per (scalar, MPC method, MPC horizon N), K_c set in a copy's data as K is above, and the
# copy's loop.c counting `mpc_control` on its own (the instructions of the control part:
# the response the MPC rows are fitted on) besides the whole loop step (push + estimate +
# control: what the MHE + MPC model is checked against). Writes
# crates/mhe-budget/data/cortex-m-mpc-points.csv (n = N·n_u, n_theta = n_x, k = K_c).
instrument_loop() { # a copy's loop.c: self-test skipped, the control part counted alone
    python3 - "$1" <<'PY'
import sys
path = sys.argv[1]
s = open(path).read()
edits = [
    ("rc = mhe_self_test(&state);", "rc = 0; /* calibration: self-test skipped */"),
    ("double per_tick = count_init(), total = 0.0, worst = 0.0;",
     "double per_tick = count_init(), total = 0.0, worst = 0.0, ctotal = 0.0, cworst = 0.0;"),
    ("            if (control(x, u, row + 1) != 0) return 1;\n",
     "            {\n#ifdef MHE_COUNT_SYSTICK\n                double cb = ticks_now(), cn;\n#endif\n"
     "                if (control(x, u, row + 1) != 0) return 1;\n#ifdef MHE_COUNT_SYSTICK\n"
     "                cn = (double)ticks_since(cb) * per_tick;\n                ctotal += cn;\n"
     "                if (cn > cworst) cworst = cn;\n#endif\n            }\n"),
    ("                total / (double)row, worst, row);\n",
     "                total / (double)row, worst, row);\n    if (row > 0)\n"
     "        fprintf(stderr, \"control part: cmean %.0f, cmax %.0f\\n\", ctotal / (double)row, cworst);\n"),
]
for old, new in edits:
    if s.count(old) != 1:
        sys.exit(f"{path}: cannot instrument (`{old.strip()}` found {s.count(old)} times)")
    s = s.replace(old, new)
open(path, "w").write(s)
PY
}
calibrate_mpc() {
    local dir="$OUT/calib-mpc"
    mkdir -p "$dir"
    local points="$dir/points.csv"
    if [ ! -s "$points" ]; then
        if [ -s "$CALIB_DIR/cortex-m-mpc-points.csv" ]; then
            grep -v '^#' "$CALIB_DIR/cortex-m-mpc-points.csv" >"$points"
        else
            echo "target,method,scenario,horizon,n,n_theta,nx,nu,ny,k,mean,max,scalar,mhe_method,mhe_horizon,mhe_n,mhe_n_theta,mhe_k,loop_mean,loop_max" >"$points"
        fi
    fi
    local spec file horizon method k tag machine label art kart mean max lmean lmax dims input scalar
    for scalar in ${CALIB_SCALARS:-f64 f32}; do
    for method in ${CALIB_MPC_METHODS:-pg fista admm-pr admm pg-jacobi fista-jacobi admm-jacobi admm-pr-jacobi}; do
        for spec in ${CALIB_MPC_SIZES:-case-study-certified:5 case-study-certified:10 cart-pendulum:30}; do
            IFS=: read -r file horizon <<<"$spec"
            local scen="$dir/$file-n$horizon.toml"
            # The MPC horizon N (in [mpc]); K_c from --kc; no sample_time (see calibrate).
            awk -v n="$horizon" '/^\[/ { sec = $0 } sec == "[mpc]" && /^horizon *=/ { print "horizon = " n; next }
                sec == "[mpc]" && /^(iterations|method) *=/ { next } /^sample_time *=/ { next } { print }' \
                "scenarios/$file.toml" >"$scen"
            if grep -q "^[^,]*,$method,$file,$horizon,[^,]*,[^,]*,[^,]*,[^,]*,[^,]*,[^,]*,[^,]*,[^,]*,$scalar," "$points"; then
                echo "==> MPC $file, N = $horizon, $method, $scalar: in $points already"
                continue
            fi
            art="$dir/$file-n$horizon-$method-$scalar"
            echo "==> calibrate the MPC: $file, N = $horizon, $method, $scalar"
            "${XTASK_CMD[@]}" export --scenario "$scen" --out "$art" --lang c --method pg \
                --k 1 --kc 1 --mpc-method "$method" --scalar "$scalar" --allow-uncertified \
                >"$art.log" 2>&1 || { cat "$art.log"; exit 1; }
            read -r -a dims <<<"$(calib_dims "$art/mhe_data.h")"
            local nseq
            nseq=$(sed -n 's/^#define MPC_NSEQ \([0-9]*\)$/\1/p' "$art/mhe_data.h")
            input="$dir/yinput-$file.csv"
            # M + 2 rows of y_j = 0.2 cos(0.7 t + j).
            awk -v rows=$((dims[0] + 2)) -v ny="${dims[5]}" 'BEGIN {
                for (t = 0; t < rows; t++) { s = "";
                    for (j = 0; j < ny; j++) s = s (s == "" ? "" : ",") sprintf("%.17g", 0.2 * cos(0.7 * t + j));
                    print s } }' >"$input"
            for k in ${CALIB_KS:-1 16 256}; do
                kart="$art-kc$k"
                rm -rf "$kart"
                cp -r "$art" "$kart"
                sed -i "s/^#define MPC_KC .*/#define MPC_KC $k/" "$kart/mhe_data.h"
                # K_c is the 4th field of the MPC problem (nx, nu, N, K_c, method, …).
                sed -i "/mhe_exported_mpc = {/{n;s/^\(    \([0-9]*, \)\{3\}\)[0-9]*,/\1$k,/}" "$kart/mhe_data.c"
                grep -A1 'mhe_exported_mpc = {' "$kart/mhe_data.c" | grep -q "^    \([0-9]*, \)\{3\}$k, MHE_" \
                    || { echo "could not set K_c = $k in $kart/mhe_data.c"; exit 1; }
                instrument_loop "$kart/loop.c"
                for target in "m4:mps2-an386:cortex-m4f" "m7:mps2-an500:cortex-m7"; do
                    IFS=: read -r tag machine label <<<"$target"
                    make -s -C "$kart" "loop-$tag.elf" DEFS=-DMHE_ALLOW_UNCERTIFIED
                    timeout 1200 qemu-system-arm -M "$machine" -nographic -monitor none -serial none \
                        -semihosting-config enable=on,target=native -icount shift=0 \
                        -kernel "$kart/loop-$tag.elf" <"$input" >"$kart/$tag.out" 2>"$kart/$tag.err"
                    mean=$(sed -n 's/.*cmean \([0-9]*\), cmax \([0-9]*\).*/\1/p' "$kart/$tag.err")
                    max=$(sed -n 's/.*cmean \([0-9]*\), cmax \([0-9]*\).*/\2/p' "$kart/$tag.err")
                    lmean=$(sed -n 's/.* mean \([0-9]*\), max \([0-9]*\).*/\1/p' "$kart/$tag.err")
                    lmax=$(sed -n 's/.* mean \([0-9]*\), max \([0-9]*\).*/\2/p' "$kart/$tag.err")
                    if [ -z "$mean" ] || [ -z "$max" ] || [ -z "$lmean" ] || [ -z "$lmax" ]; then
                        echo "no instruction count in $kart/$tag.err:"
                        cat "$kart/$tag.err"
                        exit 1
                    fi
                    echo "$label,$method,$file,$horizon,$nseq,${dims[3]},${dims[3]},${dims[4]},${dims[5]},$k,$mean,$max,$scalar,pg,${dims[0]},${dims[1]},${dims[2]},1,$lmean,$lmax" >>"$points"
                    echo "    $label, $scalar, K_c = $k: control max $max, loop step max $lmax instructions"
                done
                rm -rf "$kart"
            done
        done
    done
    done
    {
        echo "# Max (and mean) instructions of the MPC's control (mpc_control) per loop step, and of the"
        echo "# whole loop step (push + estimate + control; loop_mean, loop_max), of the exported C loop"
        echo "# program (MHE pg at K = 1, MPC at K_c = k, n = N n_u, n_theta = n_x) under qemu-system-arm"
        echo "# -icount shift=0 (emulated instructions, not cycles), measured by \`bash scripts/cortex-m.sh"
        echo "# calibrate\` (scalars: ${CALIB_SCALARS:-f64 f32}) at commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown),"
        echo "# $(date -u +%Y-%m-%d), $(arm-none-eabi-gcc --version | head -1), $(qemu-system-arm --version | head -1)."
        cat "$points"
    } >"$CALIB_DIR/cortex-m-mpc-points.csv"
    echo "wrote $CALIB_DIR/cortex-m-mpc-points.csv; fit: python3 scripts/fit-instructions.py"
}
if [ "$MODE" = calibrate ]; then
    [ "${CALIB_MHE:-1}" = 1 ] && calibrate
    [ "${CALIB_MPC:-1}" = 1 ] && calibrate_mpc
    exit 0
fi

# The table of docs/embedded.md ("The sample period as a budget"), between its markers:
# every shipped scenario (TABLE_SCENARIOS: the files to survey, default scenarios/*.toml),
# the rows chosen by the tool. Per scenario `export --survey` (per method: the smallest K
# the one verdict certifies in f64 and in f32, and the model's budget there); the f64 row
# is the method with the fewest predicted M4F instructions at its certified K, exported at
# `--k certified` (its certificate.json: instructions, fits T_s; flash and RAM of the
# replay ELFs), and where a K is certified in f32 an f32 row the same way, whose replay is
# also run under QEMU (M + 2 rows of a smooth (u, y); max instructions per step). A
# scenario with no certified K goes to the "not certified" line with its one-word reason;
# one whose every export the size limit refuses gets a row saying so. QEMU runs only for
# the f32 rows (the f64 ones would take minutes each on the M4F).
qemu_max() { # ART TAG MACHINE INPUT → the max instructions per step of the replay
    make -s -C "$1" "replay-$2.elf"
    timeout 1200 qemu-system-arm -M "$3" -nographic -monitor none -serial none \
        -semihosting-config enable=on,target=native -icount shift=0 \
        -kernel "$1/replay-$2.elf" <"$4" >"$1/$2.out" 2>"$1/$2.err"
    sed -n 's/.*mean \([0-9]*\), max \([0-9]*\).*/\2/p' "$1/$2.err"
}
table_export() { # SCALAR FILE METHOD SURVEY ROWS NOTES: the export at --k certified, its row
    local scalar=$1 file=$2 method=$3 survey=$4 rows=$5 notes=$6 linked
    local art="$OUT/table/$file-$method-$scalar" tag text data bss
    echo "==> table: $file, $method, $scalar (export at the certified K)"
    if ! "${XTASK_CMD[@]}" export --scenario "scenarios/$file.toml" --out "$art" --lang c \
        --method "$method" --k certified --scalar "$scalar" >"$art.log" 2>&1; then
        echo "- $file: certified ($method, $scalar) but not exported: $(grep -m1 -i 'error' "$art.log" | cut -c1-300)" >>"$notes"
        return 0
    fi
    local sizes=() qemu=()
    local over
    for tag in m4 m7; do
        if make -s -C "$art" "replay-$tag.elf" >"$art-$tag.make" 2>&1; then
            read -r text data bss _ < <(arm-none-eabi-size "$art/replay-$tag.elf" | tail -1)
            sizes+=("$((text + data))" "$((data + bss))")
        else
            # Larger than the QEMU boards' 4 MiB "flash" (and than any real target's).
            over=$(sed -n 's/.*overflowed by \([0-9]*\) bytes.*/\1/p' "$art-$tag.make" | head -1)
            [ -n "$over" ] || { cat "$art-$tag.make"; exit 1; }
            sizes+=("4 MiB + $over (does not link)" "–")
        fi
    done
    [ "${sizes[1]}" = – ] && linked=0 || linked=1
    # QEMU on the f32 rows whose predicted M4F step is at most TABLE_QEMU_MAX instructions
    # (default 2·10⁸: M + 2 steps in a few seconds of emulation).
    local predicted
    predicted=$(python3 -c 'import json, sys
print(int(max(b["instructions_per_step_bound"] or 0 for b in json.load(open(sys.argv[1]))["budget"]["targets"])))' "$art/certificate.json")
    if [ "$scalar" = f32 ] && [ "$linked" = 1 ] && [ "$predicted" -le "${TABLE_QEMU_MAX:-200000000}" ]; then
        local dims input="$art/input.csv"
        read -r -a dims <<<"$(calib_dims "$art/mhe_data.h")"
        awk -v rows=$((dims[0] + 2)) -v nu="${dims[4]}" -v ny="${dims[5]}" 'BEGIN {
            for (t = 0; t < rows; t++) { s = "";
                for (i = 0; i < nu; i++) s = s (s == "" ? "" : ",") sprintf("%.17g", 0.1 * sin(t + i));
                for (j = 0; j < ny; j++) s = s (s == "" ? "" : ",") sprintf("%.17g", 0.2 * cos(0.7 * t + j));
                print s } }' >"$input"
        qemu+=("$(qemu_max "$art" m4 mps2-an386 "$input")" "$(qemu_max "$art" m7 mps2-an500 "$input")")
    fi
    python3 scripts/budget-table.py row "$scalar" "$file" "$survey" "$art/certificate.json" \
        "${sizes[@]}" "${qemu[@]}" >>"$rows"
    # The artefacts of the large scenarios take MBs: keep the certificate and the log only.
    find "$art" -mindepth 1 ! -name certificate.json -delete
}
budget_table() {
    local dir="$OUT/table" rows="$OUT/table/rows.md" notes="$OUT/table/notes.md"
    local path file survey line scalar method k unc=() start
    start=$(date +%s)
    mkdir -p "$dir"
    : >"$rows"
    : >"$notes"
    for path in ${TABLE_SCENARIOS:-scenarios/*.toml}; do
        file=$(basename "$path" .toml)
        survey="$dir/$file-survey.json"
        echo "==> table: $file (export --survey: every method, f64 and f32)"
        if ! timeout "${TABLE_TIMEOUT:-900}" "${XTASK_CMD[@]}" export --scenario "$path" --survey \
            >"$survey" 2>"$dir/$file-survey.log"; then
            unc+=("$file (not computed: the survey failed or took over ${TABLE_TIMEOUT:-900} s: $(tail -1 "$dir/$file-survey.log" | cut -c1-200))")
            continue
        fi
        while read -r scalar method k; do
            case "$scalar" in
            none)
                if [ "$method" = refused ]; then
                    python3 scripts/budget-table.py refused "$file" "$survey" >>"$rows"
                else
                    unc+=("$file ($method${k:+ $k})")
                fi
                ;;
            *) table_export "$scalar" "$file" "$method" "$survey" "$rows" "$notes" ;;
            esac
        done < <(python3 scripts/budget-table.py pick "$survey")
    done
    local list="none" u
    if [ ${#unc[@]} -gt 0 ]; then
        list=""
        for u in "${unc[@]}"; do list+="${list:+; }$u"; done
    fi
    echo "Scenarios not certified (no method has a certified K in f64): $list." >>"$notes"
    echo "(\`bash scripts/cortex-m.sh table\`: $(( $(date +%s) - start )) s of wall time, $(date -u +%Y-%m-%d), commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown).)" >>"$notes"
    python3 scripts/budget-table.py write docs/embedded.md "$rows" "$notes"
    echo "wrote the table into docs/embedded.md:"
    cat "$rows" "$notes"
}
if [ "$MODE" = table ]; then
    budget_table
    exit 0
fi

# Helpers on trace.csv and replay outputs (RUN_K selects one run of trace.csv, ROWS limits
# the rows): `k` prints the run's K, `input` the replay input (u…,y… per row), `compare`
# checks a replay output against the xhat columns bit for bit, `same` two replay outputs.
csv_tools() {
    python3 - "$@" <<'PY'
import csv, os, struct, sys
mode = sys.argv[1]
def bits(line):
    return [struct.pack('<d', float(v)) for v in line.split(',')]
def lines(path):
    return [l for l in open(path).read().splitlines() if l.strip()]
if mode == 'same':
    a, b = lines(sys.argv[2]), lines(sys.argv[3])
    if len(a) < 2 or [bits(l) for l in a] != [bits(l) for l in b]:
        sys.exit(f'{sys.argv[3]} differs from {sys.argv[2]}')
    print(f'    {len(a)} output lines equal the host build bit for bit')
    sys.exit(0)
trace = sys.argv[2]
rows = list(csv.DictReader(open(trace)))
if os.environ.get('RUN_K'):
    rows = [r for r in rows if r['k'] == os.environ['RUN_K']]
if os.environ.get('ROWS'):
    rows = rows[:int(os.environ['ROWS'])]
if not rows:
    sys.exit(f'{trace}: no rows for K = {os.environ.get("RUN_K")}')
cols = rows[0].keys()
nx = sum(1 for k in cols if k.startswith('xhat'))
nu = sum(1 for k in cols if k[0] == 'u' and k[1:].isdigit())
ny = sum(1 for k in cols if k[0] == 'y' and k[1:].isdigit())
if mode == 'k':
    print(rows[0]['k'])
elif mode == 'input':
    for r in rows:
        print(','.join([r[f'u{i+1}'] for i in range(nu)] + [r[f'y{i+1}'] for i in range(ny)]))
elif mode == 'yinput':
    for r in rows:
        print(','.join(r[f'y{i+1}'] for i in range(ny)))
elif mode in ('compare', 'compare_loop'):
    got = lines(sys.argv[3])
    if len(got) != len(rows) + 1:
        sys.exit(f'{sys.argv[3]}: {len(got)} lines, expected {len(rows) + 1}')
    cols = [f'xhat{i+1}' for i in range(nx)]
    if mode == 'compare_loop':
        cols += [f'u{i+1}' for i in range(nu)]
    bad = [t for t, r in enumerate(rows)
           if bits(','.join(r[c] for c in cols)) != bits(got[t])]
    for t in bad[:3]:
        print(f'    row {t}: trace.csv and the program differ: {got[t]}')
    if bad:
        sys.exit(f'{len(bad)} of {len(rows)} rows differ from {trace}')
    what = 'xhat and u' if mode == 'compare_loop' else 'xhat'
    print(f'    {len(rows)} rows equal trace.csv\'s {what} bit for bit')
PY
}

summary="$OUT/summary.md"
{
    echo "| scenario | program | method | K | target | flash (B) | RAM (B) | instructions/step mean | max | steps |"
    echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
} >"$summary"

# target PROGRAM ART FILE INPUT LABEL_K: builds PROGRAM-m4/m7.elf, runs them under QEMU on
# INPUT, checks the host's bits, appends the size and instruction counts to the summary.
targets() {
    local program=$1 art=$2 file=$3 input=$4 label_k=$5 rows=$6
    local target tag machine label text data bss mean max
    for target in "m4:mps2-an386:Cortex-M4F" "m7:mps2-an500:Cortex-M7"; do
        IFS=: read -r tag machine label <<<"$target"
        make -s -C "$art" "$program-$tag.elf"
        echo "  $program, $label ($machine, qemu-system-arm -icount shift=0, semihosting):"
        timeout 1200 qemu-system-arm -M "$machine" -nographic -monitor none -serial none \
            -semihosting-config enable=on,target=native -icount shift=0 \
            -kernel "$art/$program-$tag.elf" <"$input" \
            >"$OUT/$file-$program-$tag.out" 2>"$OUT/$file-$program-$tag.err"
        csv_tools same "$OUT/$file-$program-host.out" "$OUT/$file-$program-$tag.out"
        if [ "${CHECK_TRACE:-0}" = 1 ]; then
            csv_tools "$([ "$program" = loop ] && echo compare_loop || echo compare)" \
                "$TRACE" "$OUT/$file-$program-$tag.out"
        fi
        read -r text data bss _ < <(arm-none-eabi-size "$art/$program-$tag.elf" | tail -1)
        mean=$(sed -n 's/.*mean \([0-9]*\), max \([0-9]*\).*/\1/p' "$OUT/$file-$program-$tag.err")
        max=$(sed -n 's/.*mean \([0-9]*\), max \([0-9]*\).*/\2/p' "$OUT/$file-$program-$tag.err")
        if [ -z "$mean" ] || [ -z "$max" ]; then
            echo "no instruction count in $OUT/$file-$program-$tag.err:"
            cat "$OUT/$file-$program-$tag.err"
            exit 1
        fi
        echo "    flash $((text + data)) B, RAM $((data + bss)) B, instructions/step mean $mean, max $max"
        echo "| $file | $program | $label_k | $label | $((text + data)) | $((data + bss)) | $mean | $max | $rows |" >>"$summary"
    done
}

# run FILE METHOD K ROWS CHECK_TRACE KC [REPRODUCE FLAGS...]
#   K: a number, `certified`, or `trace` (the K trace.csv ran); ROWS: how many rows to
#   replay; CHECK_TRACE: 1 = also compare with trace.csv (same method and K as its run);
#   KC: `-` (no MPC) or the --kc of the export (the loop program is run too; with
#   CHECK_TRACE = 1 the scenario's controller must be that MPC, so that trace.csv's run at K
#   is the loop's). The scenario is $OUT/FILE.toml when it exists, else scenarios/FILE.toml;
#   with a numeric K and CHECK_TRACE = 1 the run of trace.csv at that K is used.
run() {
    local file=$1 method=$2 k=$3 rows=$4 check=$5 kc=$6
    shift 6
    echo
    echo "==> $file: $method"
    local scenario="scenarios/$file.toml"
    [ -e "$OUT/$file.toml" ] && scenario="$OUT/$file.toml"
    QP_ITER_KERNEL=portable "${XTASK_CMD[@]}" reproduce --scenario "$scenario" \
        --out "$OUT/reproduce" "$@" >"$OUT/$file-reproduce.log" 2>&1 \
        || { tail -20 "$OUT/$file-reproduce.log"; exit 1; }
    local trace="$OUT/reproduce/$file/trace.csv"
    local run_k
    run_k=$(csv_tools k "$trace")
    [ "$k" = trace ] && k=$run_k
    if [ "$check" = 1 ] && [[ "$k" =~ ^[0-9]+$ ]]; then run_k=$k; fi
    local art="$OUT/$file-$method-c"
    local mpc_flags=()
    [ "$kc" != - ] && mpc_flags=(--kc "$kc")
    "${XTASK_CMD[@]}" export --scenario "$scenario" --out "$art" --lang c \
        --method "$method" --k "$k" "${mpc_flags[@]}" >"$OUT/$file-export.log" 2>&1 \
        || { cat "$OUT/$file-export.log"; exit 1; }
    k=$(sed -n 's/^#define MHE_K \([0-9]*\)/\1/p' "$art/mhe_data.h")
    RUN_K=$run_k ROWS=$rows csv_tools input "$trace" >"$OUT/$file-input.csv"
    echo "  host (cc), K = $k, $rows steps of trace.csv's u and y (its run at K = $run_k):"
    make -s -C "$art" replay
    "$art/replay" <"$OUT/$file-input.csv" >"$OUT/$file-replay-host.out"
    if [ "$check" = 1 ]; then
        RUN_K=$run_k ROWS=$rows csv_tools compare "$trace" "$OUT/$file-replay-host.out"
    fi
    export RUN_K=$run_k ROWS=$rows TRACE=$trace CHECK_TRACE=$check
    targets replay "$art" "$file" "$OUT/$file-input.csv" "$method, K = $k" "$rows"
    if [ "$kc" != - ]; then
        local kc_n mpc_m
        kc_n=$(sed -n 's/^#define MPC_KC \([0-9]*\)/\1/p' "$art/mhe_data.h")
        mpc_m=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['mpc']['method'])" "$art/certificate.json")
        csv_tools yinput "$trace" >"$OUT/$file-yinput.csv"
        echo "  loop (estimator + MPC $mpc_m, K_c = $kc_n) on trace.csv's y, host (cc):"
        make -s -C "$art" loop
        "$art/loop" <"$OUT/$file-yinput.csv" >"$OUT/$file-loop-host.out"
        if [ "$check" = 1 ]; then
            csv_tools compare_loop "$trace" "$OUT/$file-loop-host.out"
        fi
        targets loop "$art" "$file" "$OUT/$file-yinput.csv" \
            "$method, K = $k + MPC $mpc_m, K_c = $kc_n" "$rows"
    fi
    unset RUN_K ROWS TRACE CHECK_TRACE
}

# The certified preset with the K_c-iteration MPC as its controller (mpc.iterations = 99,
# the joint certificate's floor for its FISTA MPC at K = 243): PG at K = 243 = K_min; all 40
# steps of trace.csv's run at K = 243 (its run at the cheapest certified pair is the other);
# the replay gives its xhat and the loop program its xhat and u, bit for bit, on the host
# and on both targets.
sed 's/^terminal = "dare".*/&\niterations = 99\nmethod = "fista"/' \
    scenarios/case-study-certified.toml >"$OUT/case-study-certified-kc.toml"
grep -q '^iterations = 99' "$OUT/case-study-certified-kc.toml"
run case-study-certified-kc pg 243 40 1 99
# The cart-pendulum: ADMM-PR at its certified K_min (the smallest of the four methods; PG
# needs 140227), on the u and y of the scenario's own run (`--sim-k-cap` skips the K_min
# runs, so reproduce simulates only the scenario's K = 10); 20 steps (the M4F emulates f64
# in software); the targets' bits against the host build's.
run cart-pendulum admm-pr certified 20 0 - --sim-k-cap 1000

# f32 and the firmware's robustness on both boards: the case study's PG at the K the global
# certificate covers in f32 (`--k certified --scalar f32`, K = 13: a certified f32 artefact,
# no opt-in). On the host and under QEMU on both boards: the replay (the boards' bits equal
# the host's f32 build); the step counter set to LONG_MAX once the window is full (2^31 − 1
# on the boards' 32-bit long: 25 days at 1 kHz) changes no bit; NaN, −∞ and a value beyond
# f32's range are refused by mhe_push with the state unchanged, and the replay stops at such
# a line or at a malformed one (`0.3abc`) naming it; the M4F's max instructions per step is
# at most 168 000 (1 kHz at 168 MHz at a K certified in f32).
robustness() {
    local art="$OUT/case-study-f32-c" tag machine label prog
    echo
    echo "==> case-study: pg, f32 at the certified K; robustness on both boards"
    "${XTASK_CMD[@]}" export --scenario scenarios/case-study.toml --out "$art" --lang c --method pg \
        --k certified --scalar f32 >"$OUT/case-study-f32-export.log" 2>&1 \
        || { cat "$OUT/case-study-f32-export.log"; exit 1; }
    grep -q 'certified' "$OUT/case-study-f32-export.log"
    grep -q '^#define MHE_CERTIFIED 1$' "$art/mhe_data.h"
    local dims
    read -r -a dims <<<"$(calib_dims "$art/mhe_data.h")"
    # 2M + 4 rows of a smooth (u, y); the bad inputs replace row 3.
    awk -v rows=$((2 * dims[0] + 4)) -v nu="${dims[4]}" -v ny="${dims[5]}" 'BEGIN {
        for (t = 0; t < rows; t++) { s = "";
            for (i = 0; i < nu; i++) s = s (s == "" ? "" : ",") sprintf("%.17g", 0.1 * sin(t + i));
            for (j = 0; j < ny; j++) s = s (s == "" ? "" : ",") sprintf("%.17g", 0.2 * cos(0.7 * t + j));
            print s } }' >"$OUT/f32-input.csv"
    local bad
    for bad in nan -inf 1e39 0.3abc; do
        awk -v b="$bad" -F, 'NR == 3 { $NF = b } { print }' OFS=, "$OUT/f32-input.csv" >"$OUT/f32-bad-$bad.csv"
    done
    # The robustness programs: a copy of the artefact whose replay.c is the program (so the
    # artefact's Makefile builds it for the host and both boards with the same flags).
    mkdir -p "$art-counter" "$art-nonfinite"
    cp -r "$art"/. "$art-counter"
    cp -r "$art"/. "$art-nonfinite"
    cat >"$art-counter/replay.c" <<'C'
#include <limits.h>
#include <stdio.h>
#include "mhe.h"
#include "count.h"
#include "parse.h"
static mhe_state s;
static void show(const mhe_real *x) {
    int i;
    for (i = 0; i < MHE_NX; i++) printf(i ? ",%.17g" : "%.17g", (double)x[i]);
    printf("\n");
}
int main(void) {
    static char line[MHE_LINE_MAX];
    double v[MHE_NU + MHE_NY];
    mhe_real u[MHE_NU_BUF], y[MHE_NY];
    long lineno = 0;
    int i;
#ifdef MHE_COUNT_SYSTICK
    count_init();
#endif
    mhe_reset(&s, mhe_exported_prior);
    show(mhe_estimate(&s));
    while (mhe_read_line("counter", line, ++lineno) == 1) {
        if (mhe_parse_line("counter", line, lineno, MHE_NU + MHE_NY, "u then y", v) != 0) return 1;
        for (i = 0; i < MHE_NU; i++) u[i] = (mhe_real)v[i];
        for (i = 0; i < MHE_NY; i++) y[i] = (mhe_real)v[MHE_NU + i];
        if (lineno == MHE_M + 2) s.t = LONG_MAX;
        if (mhe_push(&s, u, y) != MHE_OK) return 1;
        show(mhe_estimate(&s));
    }
    return 0;
}
C
    cat >"$art-nonfinite/replay.c" <<'C'
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "mhe.h"
#include "count.h"
static mhe_state s, snap;
int main(void) {
    mhe_real u[MHE_NU_BUF], y[MHE_NY];
    const mhe_real bad[2] = {NAN, -INFINITY};
    int k, i, refused = 0;
#ifdef MHE_COUNT_SYSTICK
    count_init();
#endif
    for (i = 0; i < MHE_NU_BUF; i++) u[i] = (mhe_real)0.01;
    for (i = 0; i < MHE_NY; i++) y[i] = (mhe_real)0.1;
    mhe_reset(&s, mhe_exported_prior);
    for (k = 0; k < MHE_M + 3; k++) {
        if (mhe_push(&s, u, y) != MHE_OK) return 2;
        mhe_estimate(&s);
    }
    memcpy(&snap, &s, sizeof s);
    for (k = 0; k < 2; k++) {
        y[MHE_NY - 1] = bad[k];
        if (mhe_push(&s, u, y) != MHE_E_NONFINITE) return 3;
        if (memcmp(&snap, &s, sizeof s) != 0) return 4;
        refused++;
        y[MHE_NY - 1] = (mhe_real)0.1;
        u[0] = bad[k];
        if (MHE_NU > 0 && mhe_push(&s, u, y) != MHE_E_NONFINITE) return 5;
        if (memcmp(&snap, &s, sizeof s) != 0) return 6;
        refused += MHE_NU > 0;
        u[0] = (mhe_real)0.01;
    }
    if (mhe_push(&s, u, y) != MHE_OK) return 7;
    printf("refused %d, state unchanged\n", refused);
    return 0;
}
C
    for prog in "$art" "$art-counter" "$art-nonfinite"; do make -s -C "$prog" replay; done
    "$art/replay" <"$OUT/f32-input.csv" >"$OUT/f32-replay-host.out"
    "$art-counter/replay" <"$OUT/f32-input.csv" >"$OUT/f32-counter-host.out"
    csv_tools same "$OUT/f32-replay-host.out" "$OUT/f32-counter-host.out"
    "$art-nonfinite/replay" >"$OUT/f32-nonfinite-host.out"
    grep -q '^refused 4, state unchanged$' "$OUT/f32-nonfinite-host.out"
    for bad in nan -inf 1e39 0.3abc; do
        if "$art/replay" <"$OUT/f32-bad-$bad.csv" >"$OUT/f32-bad-$bad-host.out" 2>"$OUT/f32-bad-$bad-host.err"; then
            echo "the host replay accepted \`$bad\` on line 3"; exit 1
        fi
        grep -q 'line 3' "$OUT/f32-bad-$bad-host.err"
    done
    echo "  host (cc): f32 replay, counter at LONG_MAX (same bits), non-finite and malformed input refused"
    for target in "m4:mps2-an386:Cortex-M4F" "m7:mps2-an500:Cortex-M7"; do
        IFS=: read -r tag machine label <<<"$target"
        local q=(timeout 600 qemu-system-arm -M "$machine" -nographic -monitor none -serial none
            -semihosting-config enable=on,target=native -icount shift=0)
        for prog in "$art" "$art-counter" "$art-nonfinite"; do make -s -C "$prog" "replay-$tag.elf"; done
        "${q[@]}" -kernel "$art/replay-$tag.elf" <"$OUT/f32-input.csv" \
            >"$OUT/f32-replay-$tag.out" 2>"$OUT/f32-replay-$tag.err"
        csv_tools same "$OUT/f32-replay-host.out" "$OUT/f32-replay-$tag.out"
        "${q[@]}" -kernel "$art-counter/replay-$tag.elf" <"$OUT/f32-input.csv" \
            >"$OUT/f32-counter-$tag.out" 2>/dev/null
        csv_tools same "$OUT/f32-replay-host.out" "$OUT/f32-counter-$tag.out"
        "${q[@]}" -kernel "$art-nonfinite/replay-$tag.elf" >"$OUT/f32-nonfinite-$tag.out" 2>/dev/null </dev/null || true
        grep -q '^refused 4, state unchanged' "$OUT/f32-nonfinite-$tag.out" \
            || { echo "$label: mhe_push did not refuse the non-finite pairs"; exit 1; }
        for bad in nan -inf 1e39 0.3abc; do
            "${q[@]}" -kernel "$art/replay-$tag.elf" <"$OUT/f32-bad-$bad.csv" \
                >"$OUT/f32-bad-$bad-$tag.out" 2>"$OUT/f32-bad-$bad-$tag.err" || true
            grep -q 'line 3' "$OUT/f32-bad-$bad-$tag.err" \
                || { echo "$label: the replay did not refuse \`$bad\` on line 3"; cat "$OUT/f32-bad-$bad-$tag.err"; exit 1; }
            [ "$(wc -l <"$OUT/f32-bad-$bad-$tag.out")" -eq 3 ] \
                || { echo "$label: the replay printed past the refused line 3"; exit 1; }
        done
        local max
        max=$(sed -n 's/.*mean \([0-9]*\), max \([0-9]*\).*/\2/p' "$OUT/f32-replay-$tag.err")
        # Issue 36: at least 1 kHz at 168 MHz on the M4F (≤ 168 000 instructions per step).
        if [ "$tag" = m4 ] && ! [ "${max:-999999999}" -le 168000 ]; then
            echo "$label: max ${max:-?} instructions per step > 168 000: not 1 kHz at 168 MHz"
            exit 1
        fi
        echo "  $label: f32 replay = host bits (max $max instructions/step), counter at LONG_MAX = same bits, non-finite / out-of-range / malformed refused"
    done
}
[ "${CHECK_ROBUSTNESS:-1}" = 1 ] && robustness

echo
cat "$summary"
echo "(flash = text + data, RAM = data + bss of the whole program, newlib's stdio included;"
echo " instructions = SysTick ticks under -icount shift=0 times the instructions per tick of a"
echo " calibration loop: emulated instructions, not cycles; a replay step is push + estimate,"
echo " a loop step push + estimate + control)"
