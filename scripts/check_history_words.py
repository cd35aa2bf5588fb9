#!/usr/bin/env python3
"""The history rule: the product speaks of the software as it is; its history lives in git.

    scripts/check_history_words.py [--self-test] [ROOT]

Reads every file git tracks, and the untracked files it does not ignore (git ls-files --cached
--others --exclude-standard), and finds the words of a development process: numbered development
stops, issue and item numbers, "landed", "before this change", "was X, now Y", "today's build",
absolute paths of a development machine and commit hashes in prose. Prints each hit as
file:line: what: the line, and exits 1 when there is any.

Not read: this script (its patterns and self-test name the words), binary files, and the recorded
outputs of runs in docs/results/ (the report files keep the paths of the run they record).
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

# A hex word of 7-40 digits with at least one letter and one digit: an abbreviated or full commit.
HEX = r"(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b"
# After "stop N": units that make it a quantity ("the search stops 5 m short"), not a stop number.
UNITS = r"(?:%|x|ms|s|m|cm|mm|km|min|h|seconds?|minutes?|hours?|frames?|rounds?|areas?|times|iterations?|samples?)\b"

PATTERNS = [
    ("development stop", re.compile(r"\bstops?\s+\d+(?:\s*[-\u2013]\s*\d+)?(?![\d.])(?!\s*" + UNITS + ")",
                                    re.IGNORECASE)),
    ("issue number", re.compile(r"\bissues?\s+#?\d+\b|(?<![\w$&])\(#\d+\)|\b(?:PR|pull request)\s+#?\d+\b",
                                re.IGNORECASE)),
    ("item number", re.compile(r"\bItems?\s+\d+(?:\s*(?:,|and|&)\s*\d+)*:")),
    ("landed", re.compile(r"\blanded\b", re.IGNORECASE)),
    ("before/after a change", re.compile(
        r"\b(?:before|after|since|until|prior to)\s+(?:this|that|the)\s+(?:change|fix|patch|release)s?\b"
        r"|\bthis (?:change|patch|PR|pull request)\b|\bbefore this round\b"
        r"|\bthe (?:build|binary) before\b", re.IGNORECASE)),
    ("was/now", re.compile(r"(?<![\w$])\((?:was|now|previously|formerly)\s+[\w`'\"]|\(before:"
                           r"|\bwas\s+[^\s,;.()]+,?\s+now\b", re.IGNORECASE)),
    ("today's build", re.compile(r"\btoday'?s\b", re.IGNORECASE)),
    ("machine path", re.compile(r"(?<![\w.~-])/(?:work|home|Users|root)/|/tmp/(?:lmb|lead)")),
    ("commit hash", re.compile(r"\bcommits?\s+(?:at\s+)?" + HEX + r"|\((?:[A-Za-z]+\s+){0,2}" + HEX + r"\)")),
]

SELF = "scripts/check_history_words.py"
EXCLUDED_FOLDERS = ("docs/results/",)


def files(root):
    out = subprocess.run(["git", "-C", root, "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                         check=True, capture_output=True).stdout.decode("utf-8", "replace")
    return sorted({f for f in out.split("\0") if f})


def scan(root, rel):
    """(line number, pattern name, line) of each hit in one file; nothing for a binary file."""
    path = os.path.join(root, rel)
    if not os.path.isfile(path):  # deleted in the work tree but still in the index
        return []
    with open(path, "rb") as f:
        data = f.read()
    if b"\0" in data[:8192]:
        return []
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return []
    hits = []
    for number, line in enumerate(text.split("\n"), 1):
        for name, pattern in PATTERNS:
            if pattern.search(line):
                hits.append((number, name, line.strip()))
    return hits


def check(root):
    found = 0
    scanned = 0
    for rel in files(root):
        if rel == SELF or rel.startswith(EXCLUDED_FOLDERS):
            continue
        scanned += 1
        for number, name, line in scan(root, rel):
            found += 1
            print(f"{rel}:{number}: {name}: {line[:160]}")
    print(f"history words: {scanned} files, {found} hits")
    if found:
        print("state the current behaviour instead (the history rule, CONTRIBUTING.md)")
    return 1 if found else 0


def self_test():
    """The check fails on a planted development stop in a doc and on an issue number in a comment,
    names their file:line, and passes the ordinary uses of the same words."""
    clean = ("Send a stop signal; the search stops at the first calibrated area, 5 stops a frame.\n"
             "The area search stops 3 frames early. Report bugs on the GitHub issue tracker.\n"
             "The learning rate is 0.125. Stop after 10 rounds. Examples: /path/to/images, out/run.\n"
             "Each round's weights; this round's totals. A map of 1234567 keypoints (0123456789).\n"
             "const double elapsed = seconds(now - started); // the (now) newest file\n")
    cases = [
        ("docs/guide.md", clean + "Measured since stop 12 on the paper world.\n", "docs/guide.md:6"),
        ("src/a.cc", "int f();\n// The loader refuses it (issue #9).\nint g();\n", "src/a.cc:2"),
    ]
    script = os.path.abspath(__file__)
    for rel, planted, where in cases:
        with tempfile.TemporaryDirectory() as root:
            subprocess.run(["git", "init", "-q", root], check=True)
            os.makedirs(os.path.join(root, "docs"))
            with open(os.path.join(root, "docs", "clean.md"), "w") as f:
                f.write(clean)
            clean_run = subprocess.run([sys.executable, script, root], capture_output=True, text=True)
            assert clean_run.returncode == 0, clean_run.stdout
            os.makedirs(os.path.dirname(os.path.join(root, rel)), exist_ok=True)
            with open(os.path.join(root, rel), "w") as f:
                f.write(planted)
            run = subprocess.run([sys.executable, script, root], capture_output=True, text=True)
            assert run.returncode == 1, run.stdout
            assert where + ":" in run.stdout, run.stdout
            print(run.stdout.splitlines()[0])
    print("history words: self-test passed")
    return 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--self-test", action="store_true", help="check the checker on planted words")
    parser.add_argument("root", nargs="?", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    args = parser.parse_args()
    if args.self_test:
        return self_test()
    return check(args.root)


if __name__ == "__main__":
    sys.exit(main())
