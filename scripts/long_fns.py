#!/usr/bin/env python3
"""Lists functions longer than a limit (default 120 lines, signature to closing brace).

Usage: python3 scripts/long_fns.py [--limit N] DIR...   (e.g. crates/iss-certificate/src)

Test code (files named tests*.rs or *_tests.rs, and `mod tests` blocks) is skipped. Braces
are matched after dropping comments, string and char literals, so the count is the span a
reader scrolls through.
"""
import argparse
import os
import re
import sys

FN = re.compile(r"^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+\"C\"\s+)?fn\s+(\w+)")


def strip(line, state):
    """The code of `line` without comments and literals; `state` carries a block comment."""
    out, i, n = [], 0, len(line)
    while i < n:
        if state["block"]:
            j = line.find("*/", i)
            if j < 0:
                return "".join(out)
            state["block"], i = False, j + 2
            continue
        if state["raw"] is not None:
            j = line.find('"' + "#" * state["raw"], i)
            if j < 0:
                return "".join(out)
            i, state["raw"] = j + 1 + state["raw"], None
            continue
        if state["str"]:
            if line[i] == "\\":
                i += 2
                continue
            if line[i] == '"':
                state["str"] = False
            i += 1
            continue
        c = line[i]
        if line.startswith("//", i):
            break
        if line.startswith("/*", i):
            state["block"], i = True, i + 2
            continue
        m = re.match(r"b?r(#*)\"", line[i:])
        if m and (i == 0 or not (line[i - 1].isalnum() or line[i - 1] == "_")):
            state["raw"], i = len(m.group(1)), i + m.end()
            continue
        if c == '"':
            state["str"], i = True, i + 1
            continue
        m = re.match(r"'(\\.|[^\\'])'", line[i:])
        if m:
            i += m.end()
            continue
        out.append(c)
        i += 1
    return "".join(out)


def scan(path, limit):
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    state = {"block": False, "str": False, "raw": None}
    code = [strip(l, state) for l in lines]
    found, i = [], 0
    while i < len(lines):
        if re.match(r"^\s*mod tests\b", code[i]) or re.match(r"^\s*mod \w*tests\b", code[i]):
            depth, j, opened = 0, i, False
            while j < len(lines):
                depth += code[j].count("{") - code[j].count("}")
                opened |= "{" in code[j]
                if opened and depth <= 0:
                    break
                j += 1
            i = j + 1
            continue
        m = FN.match(code[i])
        if not m:
            i += 1
            continue
        depth, j, opened = 0, i, False
        while j < len(lines):
            c = code[j]
            if not opened and ";" in c and "{" not in c:
                break  # a declaration without a body
            depth += c.count("{") - c.count("}")
            opened |= "{" in c
            if opened and depth <= 0:
                break
            j += 1
        if opened:
            length = j - i + 1
            if length > limit:
                found.append((length, path, i + 1, m.group(7)))
            i += 1  # nested fns are counted too
        else:
            i = j + 1
    return found


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--limit", type=int, default=120)
    ap.add_argument("dirs", nargs="+")
    a = ap.parse_args()
    found = []
    for d in a.dirs:
        for root, _, files in os.walk(d):
            for name in files:
                if not name.endswith(".rs") or name.startswith("tests") or name.endswith("_tests.rs"):
                    continue
                found += scan(os.path.join(root, name), a.limit)
    for length, path, line, name in sorted(found, reverse=True):
        print(f"{length:5} {path}:{line} {name}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
