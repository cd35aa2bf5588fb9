#!/usr/bin/env python3
"""The documentation's links all lead somewhere.

    scripts/check_doc_links.py [--self-test] [ROOT]

Reads every Markdown file git tracks, and the untracked ones it does not ignore, and checks
  - each relative link [text](target) and image ![alt](target): the file or folder exists, and a
    #anchor names a heading of the target page (GitHub's anchors: lower case, punctuation dropped,
    spaces to hyphens, -1, -2 ... for repeated headings);
  - each page named in the text of any tracked source, script or page (docs/NAME.md, or NAME.md
    beside a page in docs/): the page exists, and a section named right after it in quotes
    (docs/pose.md "Confidence", [pose.md](pose.md), "Confidence") is a heading of that page.
Prints each broken link as file:line: what, and exits 1 when there is any.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
# A page named in text (not as a link target), optionally followed by a quoted section name.
MENTION = re.compile(r"(?<![\w/.($\{-])((?:\.\./)?(?:docs/)?[A-Za-z0-9_][A-Za-z0-9_.-]*\.md)(?![\w/(])"
                     r"(?:\)?,?\s+\(?\"([A-Za-z`][^\"\n]{1,99})\")?")
TEXT_EXTENSIONS = (".md", ".cc", ".h", ".py", ".sh", ".txt", ".cmake", ".sbatch", ".toml", ".in")
SELF = "scripts/check_doc_links.py"
# Files whose page names are examples, not references (a checker's planted cases).
NOT_REFERENCES = (SELF, "scripts/check_history_words.py")
SKIP_FOLDERS = ("build", "build-asan", "build-tsan", "out")


def files(root):
    out = subprocess.run(["git", "-C", root, "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                         check=True, capture_output=True).stdout.decode("utf-8", "replace")
    return sorted({f for f in out.split("\0") if f and os.path.isfile(os.path.join(root, f))
                   and not f.startswith(tuple(d + "/" for d in SKIP_FOLDERS))})


def slug(heading):
    """GitHub's anchor of a heading text."""
    text = re.sub(r"`([^`]*)`", r"\1", heading.strip())
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)  # a link's text
    text = text.lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def headings(path, cache={}):
    """(anchors, heading texts) of a Markdown page."""
    if path not in cache:
        anchors, texts, seen = set(), [], {}
        in_code = False
        with open(path, encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.lstrip().startswith("```"):
                    in_code = not in_code
                    continue
                m = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
                if in_code or not m:
                    continue
                texts.append(m.group(1))
                base = slug(m.group(1))
                n = seen.get(base, 0)
                seen[base] = n + 1
                anchors.add(base if n == 0 else f"{base}-{n}")
        cache[path] = (anchors, texts)
    return cache[path]


def has_section(path, name):
    """A heading of the page contains `name` (case and code marks aside)."""
    want = re.sub(r"[`*]", "", name).lower()
    return any(want in re.sub(r"[`*]", "", t).lower() for t in headings(path)[1])


def resolve_page(root, rel, name):
    """The file a page name in `rel` refers to, or None when none exists."""
    here = os.path.dirname(rel)
    candidates = [os.path.normpath(os.path.join(here, name)), os.path.normpath(name)]
    if not name.startswith(("docs/", "../")):
        candidates.append(os.path.join("docs", name))
    for c in candidates:
        if os.path.isfile(os.path.join(root, c)):
            return c
    return None


def strip_code_blocks(text):
    """The text with fenced code blocks blanked (line numbers kept)."""
    out, in_code = [], False
    for line in text.split("\n"):
        if line.lstrip().startswith("```"):
            in_code = not in_code
            out.append("")
            continue
        out.append("" if in_code else line)
    return out


def check_links(root, rel, lines, problems):
    for number, line in enumerate(lines, 1):
        for m in LINK.finditer(line):
            target = m.group(1)
            if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("//"):
                continue  # http:, https:, mailto:
            path, _, anchor = target.partition("#")
            full = os.path.normpath(os.path.join(root, os.path.dirname(rel), path)) if path else os.path.join(root, rel)
            if not os.path.exists(full):
                problems.append(f"{rel}:{number}: link to a missing file: {target}")
                continue
            if anchor and full.endswith(".md") and anchor not in headings(full)[0]:
                problems.append(f"{rel}:{number}: link to a missing heading: {target}")


def check_mentions(root, rel, lines, problems):
    markdown = rel.endswith(".md")
    for number, line in enumerate(lines, 1):
        scan = LINK.sub(lambda m: "[]" + ("" if markdown else m.group(0)), line) if markdown else line
        for m in MENTION.finditer(scan):
            name, section = m.group(1), m.group(2)
            if not markdown and not name.startswith("docs/"):
                continue  # in code, only docs/NAME.md is a reference to a page
            if name in ("README.md", "CONTRIBUTING.md") or name.endswith(("/README.md", "/CONTRIBUTING.md")):
                page = name if os.path.isfile(os.path.join(root, name)) else None
            else:
                page = resolve_page(root, rel, name)
            if page is None:
                if name.startswith("docs/") or markdown:
                    problems.append(f"{rel}:{number}: names a missing page: {name}")
                continue
            if section and page.endswith(".md") and not has_section(os.path.join(root, page), section):
                problems.append(f"{rel}:{number}: names a missing section of {page}: \"{section}\"")
        if markdown:  # a link followed by a quoted section: [pose.md](pose.md) "Confidence"
            for m in re.finditer(LINK.pattern + r",?\s+\(?\"([A-Za-z`][^\"\n]{1,99})\"", line):
                path = m.group(1).partition("#")[0]
                full = os.path.normpath(os.path.join(root, os.path.dirname(rel), path))
                if path.endswith(".md") and os.path.isfile(full) and not has_section(full, m.group(2)):
                    problems.append(f"{rel}:{number}: names a missing section of {path}: \"{m.group(2)}\"")


def check(root):
    problems = []
    scanned = 0
    for rel in files(root):
        if not rel.endswith(TEXT_EXTENSIONS) or rel in NOT_REFERENCES:
            continue
        with open(os.path.join(root, rel), "rb") as f:
            data = f.read()
        if b"\0" in data[:8192]:
            continue
        text = data.decode("utf-8", "replace")
        scanned += 1
        if rel.endswith(".md"):
            lines = strip_code_blocks(text)
            check_links(root, rel, lines, problems)
        else:
            lines = text.split("\n")
        check_mentions(root, rel, lines, problems)
    for p in problems:
        print(p)
    print(f"doc links: {scanned} files, {len(problems)} broken")
    return 1 if problems else 0


def self_test():
    """The check passes a tree whose links resolve and fails on a missing page, a missing anchor and
    a missing quoted section, naming file:line."""
    good = {
        "README.md": "# P\nSee [the guide](docs/guide.md#first-steps) and docs/guide.md \"Second part\".\n",
        "docs/guide.md": "# Guide\n## First steps\n## Second part: more\nBack to [README](../README.md).\n"
                         "![plot](results/a.png) [top](#guide)\n```\n[not a link](missing.md)\n```\n",
        "docs/results/a.png": "png",
        "src/a.cc": "// the format: docs/guide.md \"First steps\".\n",
    }
    bad = [
        ("README.md", "# P\nSee [gone](docs/gone.md).\n", "README.md:2: link to a missing file"),
        ("README.md", "# P\nSee [x](docs/guide.md#nowhere).\n", "README.md:2: link to a missing heading"),
        ("src/a.cc", "int a;\n// docs/guide.md \"No such part\"\n", "src/a.cc:2: names a missing section"),
        ("src/a.cc", "int a;\n// see docs/removed.md\n", "src/a.cc:2: names a missing page"),
    ]
    script = os.path.abspath(__file__)

    def tree(root, contents):
        subprocess.run(["git", "init", "-q", root], check=True)
        for rel, text in contents.items():
            os.makedirs(os.path.dirname(os.path.join(root, rel)) or root, exist_ok=True)
            with open(os.path.join(root, rel), "w") as f:
                f.write(text)

    with tempfile.TemporaryDirectory() as root:
        tree(root, good)
        run = subprocess.run([sys.executable, script, root], capture_output=True, text=True)
        assert run.returncode == 0, run.stdout
    for rel, text, where in bad:
        with tempfile.TemporaryDirectory() as root:
            tree(root, dict(good, **{rel: text}))
            run = subprocess.run([sys.executable, script, root], capture_output=True, text=True)
            assert run.returncode == 1 and where in run.stdout, run.stdout
            print(run.stdout.splitlines()[0])
    print("doc links: self-test passed")
    return 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--self-test", action="store_true", help="check the checker on planted broken links")
    parser.add_argument("root", nargs="?", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    args = parser.parse_args()
    if args.self_test:
        return self_test()
    return check(os.path.abspath(args.root))


if __name__ == "__main__":
    sys.exit(main())
