#!/usr/bin/python3
"""The visual-word sweep's table (the paper's Table II) from the reports of jobs/vocab_sweep.sh.

  /usr/bin/python3 jobs/vocab_table.py SWEEP_DIR

Reads SWEEP_DIR/w<N>/report.json (`lboost eval`, method "landmarkboost") and, when present,
SWEEP_DIR/w<N>/run/summary.json; prints a Markdown table: one column per word count, rows
precision@1 and MRR of the query keypoints (the best of each row in bold), then the classes,
rounds and query keypoints they were measured on.
"""
import json
import os
import re
import sys


def load(sweep):
    cols = []
    for name in os.listdir(sweep):
        m = re.fullmatch(r"w(\d+)", name)
        path = os.path.join(sweep, name, "report.json")
        if not m or not os.path.isfile(path):
            continue
        with open(path) as f:
            report = json.load(f)
        method = report.get("methods", {}).get("landmarkboost")
        if method is None:
            raise SystemExit(f"{path}: no method 'landmarkboost'")
        for key in ("precision_at_1", "mrr"):
            if not isinstance(method.get(key), (int, float)):
                raise SystemExit(f"{path}: methods.landmarkboost.{key} missing or not a number")
        cols.append((int(m.group(1)), report, method))
    if not cols:
        raise SystemExit(f"{sweep}: no w<N>/report.json")
    return sorted(cols, key=lambda c: c[0])


def row(label, values):
    best = max(values)
    cells = [f"**{v:.3f}**" if v == best else f"{v:.3f}" for v in values]
    return "| " + label + " | " + " | ".join(cells) + " |"


def main(argv):
    if len(argv) != 2:
        raise SystemExit(__doc__)
    cols = load(argv[1])
    print("| | " + " | ".join(f"{w} vw" for w, _, _ in cols) + " |")
    print("|---|" + "---|" * len(cols))
    print(row("Precision@1", [m["precision_at_1"] for _, _, m in cols]))
    print(row("MRR", [m["mrr"] for _, _, m in cols]))
    _, report, _ = cols[0]
    d = report.get("dataset", {})
    training = report.get("training", {})
    print()
    print(f"Context-only classifiers: {d.get('model_classes')} classes, {training.get('rounds')} rounds; "
          f"{d.get('query_keypoints_with_class_truth')} query keypoints with a true landmark "
          f"({d.get('query_frames')} query frames).")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
