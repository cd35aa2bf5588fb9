#!/usr/bin/python3
"""Plots of an evaluation report and a training run (the paper's Figs. 5-9), as PNG files.

  /usr/bin/python3 jobs/plots.py --report report.json --run RUN_DIR --out PLOT_DIR

Needs matplotlib (Debian: python3-matplotlib); run it with the system /usr/bin/python3.
Either input may be left out; the plots that need it are skipped.

Inputs
  report.json (`lboost eval --report`, every field documented in docs/report.md); per method the
  plots read
    "miss_rate_curve":   {"n": [...], "fppi": [...], "miss_rate": [...]}
    "pose_pr_curve":     {"threshold": [...], "recall": [...], "precision": [...]}
    "per_frame":         {"match_ms": [...], "total_ms": [...], "inlier_ratio": [...], ...}
    "pose_recall_sweep": {"ransac_iterations": [...], "seeds": [...], "mean": [...], "min": [...],
                          "max": [...]}   (optional; older reports have none)
  RUN_DIR/metrics.jsonl (`lboost train`): one JSON object a round with at least "round" (0-based),
    "cost", "validation_p1" (null or -1 when not evaluated), "sharing_size", optionally
    "validation_p1_landmarks"; a resumed run may repeat rounds, the last line of a round wins.

Outputs (in PLOT_DIR)
  miss_rate_fppi.png   average miss rate vs false positives per query (log x)       [report]
  pose_pr.png          pose precision-recall at 20 cm / 5 deg, AUC in the legend   [report]
  runtime_inlier.png   matching time per frame vs inlier ratio, means emphasized    [report]
  pose_recall_iterations.png  pose recall vs RANSAC iterations, mean and min-max over
                       the seeds                                                    [report sweep]
  training.png         training cost and validation precision@1 per round          [metrics]
  sharing_size.png     sharing-set size per round                                  [metrics]
"""
import argparse
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# Fixed colours and order so that a method looks the same in every plot and report.
METHOD_STYLE = {
    "landmarkboost": ("#d62728", "LandmarkBoost"),
    "landmarkboost_invfile": ("#ff7f0e", "LandmarkBoost + inv. file"),
    "bruteforce_hamming": ("#1f77b4", "Brute-force Hamming"),
    "hamming_ratio": ("#17becf", "Hamming + ratio test"),
    "hamming_ratio_2nn": ("#9467bd", "Hamming + ratio test (2nd observation)"),
    "faiss_hnsw_ratio": ("#8c564b", "faiss HNSW + ratio test"),
    "projected_kdtree": ("#2ca02c", "Projected 16-d kd-tree"),
}
EXTRA_COLOURS = ["#e377c2", "#7f7f7f", "#bcbd22", "#393b79", "#637939", "#843c39"]


def method_order(methods):
    known = [m for m in METHOD_STYLE if m in methods]
    return known + sorted(m for m in methods if m not in METHOD_STYLE)


def style(name, index):
    if name in METHOD_STYLE:
        return METHOD_STYLE[name]
    return EXTRA_COLOURS[index % len(EXTRA_COLOURS)], name


def finite(values):
    return [v for v in values if v is not None and isinstance(v, (int, float)) and math.isfinite(v)]


def save(fig, out_dir, name):
    path = os.path.join(out_dir, name)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print("wrote", path)


def dataset_note(report):
    d = report.get("dataset", {})
    parts = []
    if "query_frames" in d:
        parts.append(f"{d['query_frames']} query frames")
    if "query_keypoints_with_truth" in d:
        parts.append(f"{d['query_keypoints_with_truth']} keypoints with truth")
    if "landmarks" in d:
        parts.append(f"{d['landmarks']} landmarks")
    return ", ".join(parts)


def plot_miss_rate(report, out_dir):
    methods = report.get("methods", {})
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    drawn = 0
    for i, name in enumerate(method_order(methods)):
        curve = methods[name].get("miss_rate_curve")
        if not curve:
            continue
        # FPPI 0 has no place on a log axis: the first point (n = 0) is dropped.
        pts = [(f, m) for f, m in zip(curve["fppi"], curve["miss_rate"]) if f is not None and f > 0]
        if not pts:
            continue
        colour, label = style(name, i)
        mr1 = methods[name].get("miss_rate_at_fppi", {}).get("1")
        if mr1 is not None:
            label += f" (MR@1 = {mr1:.3f})"
        ax.step([p[0] for p in pts], [p[1] for p in pts], where="post", color=colour, label=label)
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o", color=colour, markersize=3)
        drawn += 1
    ax.set_xscale("log")
    ax.set_xlabel("false positives per query keypoint (FPPI)")
    ax.set_ylabel("miss rate")
    ax.set_ylim(0.0, 1.02)
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("Landmark retrieval: miss rate vs FPPI\n" + dataset_note(report), fontsize=10)
    if drawn:
        ax.legend(fontsize=8)
    save(fig, out_dir, "miss_rate_fppi.png")


def plot_pose_pr(report, out_dir):
    methods = report.get("methods", {})
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    drawn = 0
    for i, name in enumerate(method_order(methods)):
        m = methods[name]
        curve = m.get("pose_pr_curve")
        if not curve or not curve.get("recall"):
            continue
        colour, label = style(name, i)
        auc = m.get("pose_auc")
        rec = m.get("pose_recall_20cm_5deg")
        extra = []
        if auc is not None:
            extra.append(f"AUC = {auc:.3f}")
        if rec is not None:
            extra.append(f"recall = {rec:.3f}")
        if extra:
            label += " (" + ", ".join(extra) + ")"
        ax.plot(curve["recall"], curve["precision"], "-", color=colour, label=label)
        drawn += 1
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("recall (correct frames / all query frames)")
    ax.set_ylabel("precision")
    ax.grid(True, alpha=0.3)
    ax.set_title("6-DoF pose precision-recall (correct: 20 cm and 5 deg)\n" + dataset_note(report), fontsize=10)
    if drawn:
        ax.legend(fontsize=8, loc="lower left")
    save(fig, out_dir, "pose_pr.png")


def plot_runtime_inlier(report, out_dir):
    methods = report.get("methods", {})
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    all_ms = []
    drawn = 0
    for i, name in enumerate(method_order(methods)):
        m = methods[name]
        colour, label = style(name, i)
        frames = m.get("per_frame", {})
        ms = frames.get("match_ms", [])
        ratio = frames.get("inlier_ratio", [])
        pairs = [(r, t) for r, t in zip(ratio, ms) if r is not None and t is not None and t > 0]
        if pairs:
            ax.scatter([p[0] for p in pairs], [p[1] for p in pairs], s=8, color=colour, alpha=0.25,
                       linewidths=0)
            all_ms += [p[1] for p in pairs]
        mean_ms = m.get("match_ms_per_frame")
        mean_ratio = m.get("mean_inlier_ratio")
        if mean_ms is not None and mean_ratio is not None and mean_ms > 0:
            ax.scatter([mean_ratio], [mean_ms], s=90, color=colour, edgecolors="black", zorder=3,
                       label=f"{label} (mean {mean_ms:.1f} ms, {mean_ratio:.2f})")
            all_ms.append(mean_ms)
            drawn += 1
    if all_ms and max(all_ms) / max(min(all_ms), 1e-9) > 20:
        ax.set_yscale("log")
    ax.set_xlim(0.0, 1.0)
    ax.set_xlabel("inlier ratio of the frame's matches")
    ax.set_ylabel("matching time per frame [ms, single thread]")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("Runtime vs inlier ratio (faint: frames, bold: means)", fontsize=10)
    if drawn:
        ax.legend(fontsize=8)
    save(fig, out_dir, "runtime_inlier.png")


def plot_pose_recall_sweep(report, out_dir):
    """Pose recall against the RANSAC budget: the mean over the seeds, bars from min to max."""
    methods = report.get("methods", {})
    sweeps = [(i, name, methods[name]["pose_recall_sweep"]) for i, name in enumerate(method_order(methods))
              if isinstance(methods[name].get("pose_recall_sweep"), dict)]
    if not sweeps:
        print("no pose_recall_sweep in the report: pose_recall_iterations.png skipped")
        return
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    budgets = sorted({b for _, _, sw in sweeps for b in sw["ransac_iterations"]})
    # Methods side by side around each budget (a small multiplicative offset on the log axis).
    spread = 0.06
    for j, (i, name, sw) in enumerate(sweeps):
        colour, label = style(name, i)
        shift = math.exp(spread * (j - (len(sweeps) - 1) / 2))
        pts = [(b * shift, m, lo, hi) for b, m, lo, hi in zip(sw["ransac_iterations"], sw["mean"], sw["min"], sw["max"])
               if m is not None and lo is not None and hi is not None]
        if not pts:
            continue
        x = [p[0] for p in pts]
        mean = [p[1] for p in pts]
        # max(0, .): the mean of equal seeds can exceed their max by a rounding step, which errorbar refuses.
        err = [[max(0.0, p[1] - p[2]) for p in pts], [max(0.0, p[3] - p[1]) for p in pts]]
        ax.errorbar(x, mean, yerr=err, fmt="-o", color=colour, markersize=4, capsize=3, label=label)
    seeds = sweeps[0][2].get("seeds", [])
    ax.set_xscale("log")
    ax.set_xticks(budgets)
    ax.set_xticklabels([str(b) for b in budgets])
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("RANSAC iterations (budget)")
    ax.set_ylabel("pose recall (correct frames / query frames)")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(f"Pose recall vs RANSAC budget: mean, min-max over {len(seeds)} seeds\n" + dataset_note(report),
                 fontsize=10)
    ax.legend(fontsize=7, loc="lower right")
    save(fig, out_dir, "pose_recall_iterations.png")


def read_metrics(path):
    rounds = {}
    with open(path) as f:
        for line_no, line in enumerate(f, 1):
            line = line.strip()
            if not line:
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError as e:
                # A preempted run may leave a torn last line; anything else is an error.
                print(f"{path}:{line_no}: skipping unreadable line ({e})", file=sys.stderr)
                continue
            if "round" not in row:
                raise SystemExit(f"{path}:{line_no}: field 'round' missing")
            rounds[int(row["round"])] = row
    return [rounds[r] for r in sorted(rounds)]


def plot_training(rows, out_dir):
    x = [r["round"] + 1 for r in rows]
    cost = [r.get("cost") for r in rows]
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    ax.plot(x, cost, "-", color="#1f77b4", label="training cost")
    c = finite(cost)
    if c and min(c) > 0 and max(c) / min(c) > 50:
        ax.set_yscale("log")
    ax.set_xlabel("boosting round")
    ax.set_ylabel("training cost (exponential loss)", color="#1f77b4")
    ax.tick_params(axis="y", labelcolor="#1f77b4")
    ax.grid(True, alpha=0.3)
    ax2 = ax.twinx()
    # validation_p1: the background class competes; validation_p1_landmarks: ranking the landmark
    # classes only (as `lboost eval` does without background rejection).
    for key, fmt, label in (("validation_p1", "-", "validation precision@1"),
                            ("validation_p1_landmarks", "--", "validation precision@1, landmark classes only")):
        val = [(r["round"] + 1, r.get(key)) for r in rows]
        val = [(a, b) for a, b in val if b is not None and b >= 0]
        if val:
            ax2.plot([v[0] for v in val], [v[1] for v in val], fmt, color="#d62728",
                     marker="o" if len(val) <= 60 else None, markersize=3, label=label)
    ax2.set_ylim(0.0, 1.0)
    ax2.set_ylabel("validation precision@1", color="#d62728")
    ax2.tick_params(axis="y", labelcolor="#d62728")
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=8, loc="center right")
    ax.set_title("Training cost and validation precision@1 per round", fontsize=10)
    save(fig, out_dir, "training.png")


def plot_sharing(rows, out_dir):
    x = [r["round"] + 1 for r in rows]
    size = [r.get("sharing_size") for r in rows]
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    ax.plot(x, size, ".", color="#1f77b4", markersize=3, alpha=0.5, label="per round")
    # A running mean over ~2% of the rounds shows the trend.
    w = max(1, len(size) // 50)
    if len(size) > 2 * w and w > 1:
        sm = [sum(size[i:i + w]) / w for i in range(len(size) - w + 1)]
        ax.plot(x[w - 1:], sm, "-", color="#d62728", label=f"running mean ({w} rounds)")
    ax.set_xlabel("boosting round")
    ax.set_ylabel("sharing-set size (classes sharing the stump)")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Sharing-set size per round", fontsize=10)
    save(fig, out_dir, "sharing_size.png")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--report", help="report.json from lboost eval")
    p.add_argument("--run", help="training run dir (reads RUN/metrics.jsonl)")
    p.add_argument("--metrics", help="a metrics.jsonl file (instead of --run)")
    p.add_argument("--out", required=True, help="folder for the PNG files (created)")
    a = p.parse_args(argv)
    if not (a.report or a.run or a.metrics):
        p.error("give --report and/or --run/--metrics")
    os.makedirs(a.out, exist_ok=True)
    if a.report:
        with open(a.report) as f:
            report = json.load(f)
        if not isinstance(report.get("methods"), dict):
            raise SystemExit(f"{a.report}: field 'methods' missing or not an object")
        plot_miss_rate(report, a.out)
        plot_pose_pr(report, a.out)
        plot_runtime_inlier(report, a.out)
        plot_pose_recall_sweep(report, a.out)
    metrics = a.metrics or (os.path.join(a.run, "metrics.jsonl") if a.run else None)
    if metrics:
        rows = read_metrics(metrics)
        if not rows:
            raise SystemExit(f"{metrics}: no rounds")
        plot_training(rows, a.out)
        plot_sharing(rows, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
