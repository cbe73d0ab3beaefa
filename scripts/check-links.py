#!/usr/bin/env python3
"""Checks that every relative link of every Markdown file git tracks (or
would track) resolves to a file, and that every `docs/...` path named in
code, scripts and text exists: the documentation moves without leaving a
dangling reference behind.

    python3 scripts/check-links.py     # lists what does not resolve, exit 1
"""
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# A path the tests make up on purpose (a default "measured on" a test page).
MADE_UP = {"docs/test.md"}


def files():
    out = subprocess.run(
        ["git", "-C", ROOT, "ls-files", "--cached", "--others", "--exclude-standard"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    for rel in out:
        path = os.path.join(ROOT, rel)
        if not rel.startswith("vendor/") and os.path.isfile(path):
            yield rel, path


def main():
    bad = []
    for rel, path in files():
        try:
            text = open(path, encoding="utf-8").read()
        except UnicodeDecodeError:
            continue
        if rel.endswith(".md"):
            for m in re.finditer(r"(?:\]\(|src=\")([^)\"\s]+)", text):
                target = m.group(1)
                if re.match(r"^[a-z]+:", target) or target.startswith("#"):
                    continue
                where = os.path.normpath(os.path.join(os.path.dirname(path), target.split("#")[0]))
                if not os.path.exists(where):
                    bad.append(f"{rel}: link {target}")
        for m in re.finditer(r"docs/[A-Za-z0-9_/-]+\.(?:md|png|gif|csv|json)", text):
            if m.group(0) not in MADE_UP and not os.path.exists(os.path.join(ROOT, m.group(0))):
                bad.append(f"{rel}: path {m.group(0)}")
    for b in bad:
        print(b)
    print(f"{len(bad)} unresolved")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
