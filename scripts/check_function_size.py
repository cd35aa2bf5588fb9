#!/usr/bin/env python3
"""The size rule of the project's C++: no function body longer than MAX_LINES lines, except the
pybind11 module tables (a binding table is a list, not logic).

    scripts/check_function_size.py [--max-lines N] [--list N] [--self-test] [ROOT]

Reads every tracked .cc/.c/.h file of the product (common/, infer/, train/, python/src/, tools/; git
ls-files) and finds each function defined at namespace scope: a line at column 0 that ends a signature with '{',
up to the matching '}' at column 0. Prints the functions over the limit with file:line and length and
exits 1 when there is any; --list N prints the N longest instead (exit 0).
"""
import argparse
import os
import re
import subprocess
import sys

MAX_LINES = 120
FOLDERS = ("common/", "infer/", "train/", "python/src/", "tools/")
EXEMPT = (re.compile(r"^PYBIND11_MODULE\("),)
NOT_FUNCTIONS = re.compile(r"^(namespace|struct|class|enum|union|extern|TEST|TEST_F|TEST_P|TYPED_TEST|INSTANTIATE_)\b")


def functions(path):
    """(line number, signature, body lines) of each namespace-scope function in the file."""
    with open(path, encoding="utf-8", errors="replace") as f:
        lines = f.read().split("\n")
    out = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line or line[0].isspace() or line.startswith(("#", "//", "}", "/*", "*")):
            i += 1
            continue
        # A declaration starts at column 0; its signature runs to the line that ends with '{' or ';'.
        start = i
        while i < len(lines) and not lines[i].rstrip().endswith(("{", ";", "}")) and i - start < 20:
            i += 1
        if i >= len(lines):
            break
        signature = " ".join(l.strip() for l in lines[start:i + 1])
        if lines[i].rstrip().endswith("{") and "(" in signature and not NOT_FUNCTIONS.match(signature) \
                and "=" not in signature.split("(")[0]:
            end = i + 1
            while end < len(lines) and not lines[end].startswith("}"):
                end += 1
            out.append((start + 1, signature, end - i - 1))
            i = end
        i += 1
    return out


def self_test():
    """The check finds a function one line over the limit, wrapped signatures included, and passes the
    exempt binding table and a function at the limit."""
    import tempfile
    body = lambda n: "".join(f"  x += {i};\n" for i in range(n))
    text = ("int at_limit(int x) {\n" + body(MAX_LINES) + "}\n\n"
            "namespace {\n\nstd::vector<int> over(const std::vector<int>& a,\n"
            "                      int b) {\n" + body(MAX_LINES + 1) + "}\n\n}  // namespace\n\n"
            "PYBIND11_MODULE(_core, m) {\n" + body(3 * MAX_LINES) + "}\n")
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "a.cc")
        with open(path, "w") as f:
            f.write(text)
        found = {sig.split("(")[0].split()[-1]: length for _, sig, length in functions(path)}
    assert found.get("at_limit") == MAX_LINES, found
    assert found.get("over") == MAX_LINES + 1, found
    assert found.get("PYBIND11_MODULE") == 3 * MAX_LINES, found
    assert any(e.match("PYBIND11_MODULE(_core, m) {") for e in EXEMPT)
    print("function size: self-test passed")
    return 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--max-lines", type=int, default=MAX_LINES)
    parser.add_argument("--list", type=int, default=0)
    parser.add_argument("--self-test", action="store_true", help="check the checker on made-up functions")
    parser.add_argument("root", nargs="?", default=os.path.join(os.path.dirname(__file__), ".."))
    args = parser.parse_args()
    if args.self_test:
        return self_test()
    files = subprocess.run(["git", "-C", args.root, "ls-files", "--cached", "--others", "--exclude-standard", "*.cc", "*.c", "*.h"], check=True,
                           capture_output=True, text=True).stdout.split()
    found = []
    for rel in files:
        if not rel.startswith(FOLDERS):
            continue
        for line, signature, length in functions(os.path.join(args.root, rel)):
            if any(e.match(signature) for e in EXEMPT):
                continue
            found.append((length, rel, line, signature))
    found.sort(reverse=True)
    if args.list:
        for length, rel, line, signature in found[:args.list]:
            print(f"{length:5d}  {rel}:{line}  {signature[:100]}")
        return 0
    over = [f for f in found if f[0] > args.max_lines]
    for length, rel, line, signature in over:
        print(f"{rel}:{line}: {length} lines (limit {args.max_lines}): {signature[:100]}")
    print(f"function size: {len(found)} functions, {len(over)} over {args.max_lines} lines")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
