#!/usr/bin/env python3
"""docs/embedded.md's budget table from `cargo xtask export --survey` (the tool's choice, not
a hand-picked list): `bash scripts/cortex-m.sh table` calls it.

  pick SURVEY                 the rows of one scenario: `f64 METHOD K`, `f32 METHOD K` (the
                              method with the fewest predicted M4F instructions per step at
                              its certified K in that scalar), or `none WORD: REASON`
  row SCALAR FILE SURVEY CERT F4 R4 F7 R7 [Q4 Q7]
                              one table row from the survey and the export's certificate.json
                              (flash F, RAM R of the replay ELFs; Q: QEMU's max instructions)
  refused FILE SURVEY         the row of a scenario whose every export the size limit refuses
  write DOC ROWS NOTES        the rows and the notes between the markers of DOC
"""
import json
import sys


def m4_bound(s):
    """The predicted M4F instructions (the bound the verdict uses) of a scalar survey."""
    for b in s["budget"]:
        if b["target"] == "cortex-m4f" and b["instructions_per_step_bound"] is not None:
            return b["instructions_per_step_bound"]
    return float("inf")


def pick(path):
    doc = json.load(open(path))
    methods = doc["methods"]
    out = []
    for scalar in ("f64", "f32"):
        ok = [m for m in methods if m[scalar]["k"] is not None]
        if ok:
            best = min(ok, key=lambda m: (m4_bound(m[scalar]), m[scalar]["k"]))
            out.append(f"{scalar} {best['method']} {best[scalar]['k']}")
    if not out:
        words = [m["f64"]["verdict"] for m in methods]
        if all(w == "refused" for w in words):
            word = "refused"
        elif "not_computed" in words:
            word = "not computed"
        elif "void" in words:
            word = "void"
        else:
            word = "not certified"
        out.append(f"none {word}")
    print("\n".join(out))


def mi(v):
    if v is None:
        return "–"
    return f"{v / 1e6:.2f} M" if v >= 1e6 else f"{v / 1e3:.1f} k"


def us(v):
    if v is None:
        return "–"
    return f"{v / 1e3:.1f} ms" if v >= 1e3 else f"{v:.0f} µs"


def verdict(b, k):
    v = b["fits_sample_time"]
    if v == "fits":
        return f"yes (margin {b['margin'] * 100:.0f} %, K ≤ {b['k_max_fitting']})"
    if v == "does_not_fit":
        if b["k_max_fitting"] is None:
            return f"no, not even K = 1 (certified K = {k})"
        return f"no: fits only K ≤ {b['k_max_fitting']}, certified K = {k}"
    if "sample period" in (b["reason"] or ""):
        return "no T_s"
    return "not computed: " + (b["reason"] or "")


def k_cell(s):
    if s["k"] is not None:
        return f"{s['k']} ({s['certificate']})"
    return f"not covered: {s['short_reason']}"


def row(scalar, file, survey, cert, f4, r4, f7, r7, q4=None, q7=None):
    sv = {m["method"]: m for m in json.load(open(survey))["methods"]}
    c = json.load(open(cert))
    m = sv[c["method"]]
    if c["iterations"] != m[scalar]["k"]:
        sys.exit(f"{file}: the export's K = {c['iterations']} is not the survey's {m[scalar]['k']}")
    t = {b["target"]: b for b in c["budget"]["targets"]}
    m4, m7 = t["cortex-m4f"], t["cortex-m7"]
    k = c["iterations"]
    ex = " (extrapolated)" if m4["extrapolated"] else ""
    ins = f"{mi(m4['instructions_per_step_bound'])} / {mi(m7['instructions_per_step_bound'])}{ex}"
    if q4 and q7:
        ins += f"; QEMU max {int(q4):,} / {int(q7):,}".replace(",", " ")
    name = file if scalar == "f64" else f"{file} (f32 build)"
    print(
        f"| {name} | {c['method']} | {k_cell(m['f64'])} | {k_cell(m['f32'])} | {ins} | "
        f"{us(m4['micros_per_step'])} / {us(m7['micros_per_step'])} | {f4} / {f7} | {r4} / {r7} | "
        f"{verdict(m4, k)} / {verdict(m7, k)} |"
    )


def refused(file, survey):
    """A scenario every method of which the export refuses before the certificate (its size
    limit): a row with the reason (the smallest export's size)."""
    import re

    ms = json.load(open(survey))["methods"]
    reasons = [m[s]["reason"] for m in ms for s in ("f64", "f32")]
    mib = lambda r: float(re.search(r"≈ ([0-9.]+) MiB", r).group(1))
    reason = min(reasons, key=mib)
    n_z = re.search(r"n_z = ([0-9]+)", reason).group(1)
    limit = re.search(r"limit of\s+([0-9]+) MiB", reason).group(1)
    what = f"dense bound {mib(reason):.0f}–{max(map(mib, reasons)):.0f} MiB of data, n_z = {n_z}; limit {limit} MiB"
    print(f"| {file} | every method | refused before the certificate: the export's size limit ({what}) "
          "| – | – | – | – | – | – |")


def write(doc, rows, notes):
    text = open(doc).read()
    begin, end = "<!-- budget-table:begin -->\n", "<!-- budget-table:end -->"
    head = (
        "| scenario | method | certified K, f64 (by) | certified K, f32 (by) | instructions/step "
        "M4F / M7 | µs at 168 / 480 MHz | flash M4F / M7 (B) | RAM M4F / M7 (B) | fits T_s: M4F / M7 |\n"
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n"
    )
    i, j = text.index(begin) + len(begin), text.index(end)
    body = head + open(rows).read() + "\n" + open(notes).read()
    open(doc, "w").write(text[:i] + body + text[j:])


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    {"pick": pick, "row": row, "refused": refused, "write": write}[cmd](*args)
