#!/usr/bin/env python3
"""Markdown tables of evaluation reports (`lboost eval --report`, fields: docs/report.md).

  jobs/results_table.py table REPORT.json [--seven-scenes]
      one row per method: P@1, MRR, pose recall (one RANSAC seed, and mean [min, max] over the
      seeds at the default budget), precision / recall of the poses reported localized by the
      calibrated rule, thread CPU ms a frame (matching + pose)
  jobs/results_table.py summary-header
  jobs/results_table.py summary REPORT.json --name NAME --command CMD
      the header and one row of the README's results table: LandmarkBoost against exact Hamming
      and Hamming + ratio test on one data set, with the command that reproduces it
  jobs/results_table.py sanitize REPORT.json --out FILE --replace /abs/path=PLACEHOLDER ...
      a copy of the report whose strings name no folder of the machine that ran it: each given
      prefix (longest first) becomes its placeholder, e.g. OUT/model.lbm
  jobs/results_table.py splice PAGE.md --name NAME --text FILE
      replaces the lines between <!-- results:NAME --> and <!-- /results:NAME --> in PAGE.md by
      the contents of FILE (a page without those markers is left alone)

Only the standard library; any python3 runs it. jobs/results.sh calls it.
"""
import argparse
import json
import os
import sys

METHODS = [  # report key, what the tables call it
    ("landmarkboost", "LandmarkBoost"),
    ("landmarkboost_invfile", "LandmarkBoost, inverted file"),
    ("bruteforce_hamming", "exact Hamming (OpenCV BFMatcher)"),
    ("hamming_ratio", "Hamming + ratio test"),
    ("hamming_ratio_2nn", "Hamming + 2-NN ratio test"),
    ("faiss_hnsw_ratio", "faiss binary HNSW + ratio test"),
    ("projected_kdtree", "projected 16-d kd-tree"),
]


def number(value, digits=3):
    """A report number as text; '-' for null, the string itself for "inf"."""
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    return f"{value:.{digits}f}"


def sweep_at_default(method, settings):
    """(mean, min, max) pose recall over the seeds at the reported budget, or None."""
    sweep = method.get("pose_recall_sweep")
    if not sweep or not sweep.get("ransac_iterations"):
        return None
    budgets = sweep["ransac_iterations"]
    budget = settings.get("ransac_iterations")
    i = budgets.index(budget) if budget in budgets else len(budgets) - 1
    return sweep["mean"][i], sweep["min"][i], sweep["max"][i]


def calibrated(method):
    """(precision, recall) of the poses the calibrated rule reports localized, or None."""
    rule = method.get("pose_confidence", {}).get("calibrated_rule")
    if not rule:
        return None
    return rule.get("precision"), rule.get("recall")


def machine(report):
    m = report.get("settings", {}).get("machine", {})
    if not m:
        return "machine not recorded"
    return f"{m.get('cpu_model', '?')}, {m.get('logical_cores', '?')} logical cores"


def table(report, seven_scenes):
    settings = report.get("settings", {})
    data = report.get("dataset", {})
    seeds = settings.get("ransac_sweep_seeds", "?")
    budget = settings.get("ransac_iterations", "?")
    lines = [
        f"{data.get('query_frames', '?')} query frames, {data.get('query_keypoints_with_class_truth', '?')} query "
        f"keypoints whose landmark is one of the model's {data.get('model_classes', '?')} classes; "
        f"times on {machine(report)}, one thread.",
        "",
    ]
    header = ["method", "P@1", "MRR", "pose recall 20 cm / 5 deg", f"over {seeds} seeds, {budget} it.",
              "reported: precision / recall"]
    if seven_scenes:
        header += ["5 cm / 5 deg", "median error, all frames"]
    header += ["CPU ms a frame"]
    lines.append("| " + " | ".join(header) + " |")
    lines.append("|" + "---|" * len(header))
    methods = report.get("methods", {})
    for key, name in METHODS + [(k, k) for k in methods if k not in dict(METHODS)]:
        if key not in methods:
            continue
        m = methods[key]
        sweep = sweep_at_default(m, settings)
        cal = calibrated(m)
        row = [f"{name} (`{key}`)" if name != key else f"`{key}`", number(m.get("precision_at_1")),
               number(m.get("mrr")), number(m.get("pose_recall_20cm_5deg")),
               f"{number(sweep[0])} [{number(sweep[1])}, {number(sweep[2])}]" if sweep else "-",
               f"{number(cal[0])} / {number(cal[1])}" if cal else "-"]
        if seven_scenes:
            pos = m.get("median_position_error_all_frames_m")
            rot = m.get("median_rotation_error_all_frames_deg")
            row += [number(m.get("pose_recall_5cm_5deg")),
                    f"{number(pos)} m, {number(rot, 2)} deg" if pos is not None else "-"]
        row += [number(m.get("cpu_ms_per_frame"), 1)]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + walk_table(report)


def walk_calibration_words(calibration):
    """What the walk verdict had beside the frame rule: the walk rule, the agreement, or neither."""
    if not calibration.get("fitted", False):
        return " (not fitted)"
    if not calibration.get("adds", True):
        return " (agreement only)"
    return "" if calibration.get("agreement") else " (no agreement)"


def walk_means(method):
    """(reported right, precision) of the walk verdict, means over the seeds; None without walks."""
    totals = method.get("pose_confidence", {}).get("walk", {}).get("total")
    if not totals:
        return None
    n = len(totals)
    return (sum(t["walk_rule"]["reported_right"] for t in totals) / n,
            sum(t["walk_rule"]["precision"] for t in totals) / n)


def walk_table(report):
    """Walks: the frame rule alone and the walk verdict over the query sessions tracked frame after frame,
    mean [min, max] over the RANSAC seeds (pose_confidence.walk of lboost eval)."""
    rows, seeds = [], 0
    methods = report.get("methods", {})
    for key, name in METHODS + [(k, k) for k in methods if k not in dict(METHODS)]:
        walk = methods.get(key, {}).get("pose_confidence", {}).get("walk")
        if not walk or not walk.get("total"):
            continue
        totals = walk["total"]
        seeds = len(totals)

        def rng(rule, field, digits):
            v = [t[rule][field] for t in totals]
            return f"{number(sum(v) / len(v), digits)} [{number(min(v), digits)}, {number(max(v), digits)}]"

        outside = totals[0]["walk_rule"].get("outside_frames", 0)
        rows.append([f"{name} (`{key}`)" if name != key else f"`{key}`", str(totals[0]["walk_rule"]["frames"]),
                     str(totals[0]["walk_rule"]["frames_right"]), rng("frame_rule", "reported_right", 1),
                     rng("frame_rule", "precision", 3),
                     rng("walk_rule", "reported_right", 1) + walk_calibration_words(walk.get("calibration", {})),
                     rng("walk_rule", "precision", 3),
                     rng("walk_rule", "outside_reported", 1) + f" of {outside}" if outside else "-"])
    if not rows:
        return ""
    header = ["method", "frames", "right (seed 0)", "frame rule: reported right", "precision",
              "walk verdict: reported right", "precision", "outside frames reported"]
    lines = ["", "", "Walks: each query session tracked frame after frame (docs/walks.md); mean [min, max] over "
             f"{seeds} RANSAC seeds.", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


SUMMARY_HEADER = ("| data set (command) | P@1: LandmarkBoost / exact Hamming | pose recall: LandmarkBoost / "
                  "Hamming + ratio | reported poses: precision / recall | tracked as a walk, reported right "
                  "(precision): LandmarkBoost / Hamming + ratio | CPU ms a frame: LandmarkBoost / "
                  "exact Hamming |\n|---|---|---|---|---|---|")


def summary(report, name, command):
    methods = report.get("methods", {})
    settings = report.get("settings", {})
    lb, ham, ratio = (methods.get(k, {}) for k in ("landmarkboost", "bruteforce_hamming", "hamming_ratio"))

    def recall(m):
        sweep = sweep_at_default(m, settings)
        return number(sweep[0]) if sweep else number(m.get("pose_recall_20cm_5deg"))

    def walked(m):
        w = walk_means(m)
        return f"{number(w[0], 1)} ({number(w[1])})" if w else "-"

    cal = calibrated(lb)
    cells = [f"{name} (`{command}`)",
             f"{number(lb.get('precision_at_1'))} / {number(ham.get('precision_at_1'))}",
             f"{recall(lb)} / {recall(ratio)}",
             f"{number(cal[0])} / {number(cal[1])}" if cal else "-",
             f"{walked(lb)} / {walked(ratio)}",
             f"{number(lb.get('cpu_ms_per_frame'), 1)} / {number(ham.get('cpu_ms_per_frame'), 1)}"]
    return "| " + " | ".join(cells) + " |"


def sanitize(value, replacements):
    """`value` with every string's folder prefixes replaced (longest prefix first)."""
    if isinstance(value, dict):
        return {k: sanitize(v, replacements) for k, v in value.items()}
    if isinstance(value, list):
        return [sanitize(v, replacements) for v in value]
    if isinstance(value, str):
        for prefix, placeholder in replacements:
            value = value.replace(prefix, placeholder)
    return value


def splice(page, name, text):
    """Replaces the block between the page's markers of `name`; False when it has none."""
    with open(page, encoding="utf-8") as f:
        lines = f.read().split("\n")
    begin, end = f"<!-- results:{name} -->", f"<!-- /results:{name} -->"
    if begin not in lines or end not in lines:
        return False
    i, j = lines.index(begin), lines.index(end)
    if j < i:
        raise ValueError(f"{page}: {end} comes before {begin}")
    lines[i + 1:j] = text.rstrip("\n").split("\n")
    with open(page + ".tmp", "w", encoding="utf-8") as f:
        f.write("\n".join(lines))
    os.replace(page + ".tmp", page)
    return True


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("mode", choices=["table", "summary", "summary-header", "sanitize", "splice"])
    parser.add_argument("report", nargs="?", help="report.json of lboost eval")
    parser.add_argument("--seven-scenes", action="store_true", help="add the 7-Scenes columns")
    parser.add_argument("--name", default="data set", help="summary: the data set's name")
    parser.add_argument("--command", default="", help="summary: the command that reproduces the row")
    parser.add_argument("--replace", action="append", default=[], metavar="PREFIX=PLACEHOLDER",
                        help="sanitize: a folder prefix and what it becomes (repeatable)")
    parser.add_argument("--out", help="sanitize: the file to write")
    parser.add_argument("--text", help="splice: the file whose contents go between the markers")
    args = parser.parse_args()
    if args.mode == "summary-header":
        print(SUMMARY_HEADER)
        return 0
    if not args.report:
        parser.error("REPORT.json (or PAGE.md) is required")
    if args.mode == "splice":
        if not args.text:
            parser.error("splice needs --name NAME --text FILE")
        with open(args.text, encoding="utf-8") as f:
            done = splice(args.report, args.name, f.read())
        print(f"results_table.py: {args.report}: " + ("results:" + args.name + " replaced" if done else
                                                      "no results:" + args.name + " markers, left alone"))
        return 0
    try:
        with open(args.report, encoding="utf-8") as f:
            report = json.load(f)
    except (OSError, ValueError) as e:
        print(f"results_table.py: {args.report}: {e}", file=sys.stderr)
        return 1
    if not isinstance(report, dict) or "methods" not in report:
        print(f"results_table.py: {args.report}: not an lboost eval report (no methods)", file=sys.stderr)
        return 1
    if args.mode == "sanitize":
        if not args.out:
            parser.error("sanitize needs --out FILE")
        pairs = [r.split("=", 1) for r in args.replace]
        if any(len(p) != 2 or not p[0] for p in pairs):
            parser.error("--replace takes PREFIX=PLACEHOLDER")
        pairs.sort(key=lambda p: -len(p[0]))
        with open(args.out, "w", encoding="utf-8") as f:
            json.dump(sanitize(report, pairs), f, indent=2)
            f.write("\n")
        return 0
    if args.mode == "table":
        print(table(report, args.seven_scenes))
    else:
        print(summary(report, args.name, args.command))
    return 0


if __name__ == "__main__":
    sys.exit(main())
