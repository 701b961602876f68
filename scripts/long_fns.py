#!/usr/bin/env python3
"""Lists Rust functions longer than a limit (default 120 lines), from `fn` to its closing brace.

Usage: scripts/long_fns.py [--limit N] [PATH ...]   (default: the workspace, target/ skipped)

Braces are matched on the source with comments, strings and character literals skipped, so a
function inside a macro body (`multiversion! { fn ... }`) counts too. Test code (files under
`tests/`, `tests.rs`, or after `#[cfg(test)]`) is marked `test`; examples and tools `tool`.
Exit status 1 when a production function is over the limit.
"""

import os
import re
import sys


def code_mask(src):
    """`src` with comments, strings and char literals blanked (newlines kept)."""
    out = list(src)
    i, n = 0, len(src)

    def blank(a, b):
        for k in range(a, b):
            if out[k] != "\n":
                out[k] = " "

    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
            blank(i, j)
            i = j
        elif src.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if src.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif src.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            blank(i, j)
            i = j
        elif (m := re.compile(r'b?r(#*)"').match(src, i)) and (i == 0 or not (src[i - 1].isalnum() or src[i - 1] == "_")):
            end = '"' + m.group(1)
            j = src.find(end, m.end())
            j = n if j < 0 else j + len(end)
            blank(i, j)
            i = j
        elif c == '"':
            j = i + 1
            while j < n and src[j] != '"':
                j += 2 if src[j] == "\\" else 1
            blank(i, j + 1)
            i = j + 1
        elif c == "'":
            # A char literal ('x', '\n', '\u{..}') or a lifetime ('a).
            if i + 1 < n and src[i + 1] == "\\":
                j = src.find("'", i + 2)
                blank(i, j + 1)
                i = j + 1
            elif i + 2 < n and src[i + 2] == "'":
                blank(i, i + 3)
                i += 3
            else:
                i += 1
        else:
            i += 1
    return "".join(out)


FN = re.compile(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)")


def functions(src):
    """(name, first line, line count) of every function with a body."""
    code = code_mask(src)
    line_at = [0] * (len(code) + 1)
    line = 1
    for k, ch in enumerate(code):
        line_at[k] = line
        if ch == "\n":
            line += 1
    line_at[len(code)] = line
    found = []
    for m in FN.finditer(code):
        # The body starts at the first `{` outside parentheses and brackets; `;` means none.
        depth, j = 0, m.end()
        while j < len(code):
            ch = code[j]
            if ch in "([<" and not (ch == "<" and depth < 0):
                depth += ch != "<"
            elif ch in ")]":
                depth -= 1
            elif ch == ";" and depth == 0:
                j = -1
                break
            elif ch == "{" and depth == 0:
                break
            j += 1
        if j < 0 or j >= len(code):
            continue
        level, k = 0, j
        while k < len(code):
            if code[k] == "{":
                level += 1
            elif code[k] == "}":
                level -= 1
                if level == 0:
                    break
            k += 1
        first = line_at[m.start()]
        found.append((m.group(1), first, line_at[min(k, len(code))] - first + 1))
    return found


def test_ranges(src):
    """Line ranges of the `#[cfg(test)] mod name { ... }` blocks of `src`."""
    code = code_mask(src)
    ranges = []
    for m in re.finditer(r"#\[cfg\(test\)\]\s*mod\s+\w+\s*\{", code):
        level, k = 0, m.end() - 1
        while k < len(code):
            level += {"{": 1, "}": -1}.get(code[k], 0)
            if level == 0:
                break
            k += 1
        ranges.append((code.count("\n", 0, m.start()) + 1, code.count("\n", 0, k) + 1))
    return ranges


def kind(path, src, first_line):
    parts = path.split(os.sep)
    if "tests" in parts or path.endswith("tests.rs") or "benches" in parts:
        return "test"
    if "examples" in parts or "tools" in parts[:2]:
        return "tool"
    if any(a <= first_line <= b for a, b in test_ranges(src)):
        return "test"
    return "prod"


def main(argv):
    limit = 120
    if len(argv) >= 2 and argv[0] == "--limit":
        limit, argv = int(argv[1]), argv[2:]
    roots = argv or ["."]
    bad = 0
    rows = []
    for root in roots:
        for dirpath, dirs, files in os.walk(root):
            dirs[:] = sorted(d for d in dirs if d not in ("target", ".git"))
            for f in sorted(files):
                if not f.endswith(".rs"):
                    continue
                path = os.path.normpath(os.path.join(dirpath, f))
                src = open(path, encoding="utf-8").read()
                for name, first, lines in functions(src):
                    if lines > limit:
                        k = kind(path, src, first)
                        bad += k == "prod"
                        rows.append((lines, k, f"{path}:{first}", name))
    for lines, k, where, name in sorted(rows, reverse=True):
        print(f"{lines:5} {k:4} {where} {name}")
    print(f"{len(rows)} functions over {limit} lines, {bad} in production code")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
