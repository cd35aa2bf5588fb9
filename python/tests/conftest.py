"""Fixtures of the landmarkboost tests: the tiny rendered world of the ctest fixture lmb_tiny_world
(test/train/export: `lboost world --preset tiny --seed 1` + `lboost map`), and once per session a
model trained on it with the lboost binary of this build (vocab -> train -> export), its query
frames localized by `lboost localize` and evaluated by `lboost eval`.

Environment (set by the ctest python/pytest): LMB_LBOOST (the lboost binary), LMB_TINY_DIR (the
tiny world's folder: map.h5 and collection/). Tests that need them skip when they are absent.
"""
import os
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest


def run_lboost(*args, cwd=None):
    lboost = os.environ["LMB_LBOOST"]
    r = subprocess.run([lboost, *map(str, args)], capture_output=True, text=True, cwd=cwd)
    if r.returncode != 0:
        raise AssertionError(f"lboost {' '.join(map(str, args))} failed ({r.returncode}):\n{r.stderr}")
    return r.stdout


# The non-default options of the second comparison run, as lboost flags and as LocalizerOptions.
OTHER_FLAGS = ["--top-k", "3", "--pose-top-k", "2", "--inverted-file", "--inverted-file-words", "2",
               "--min-margin", "-0.5", "--ransac-iterations", "300", "--max-error", "6", "--min-inliers", "8",
               "--seed", "5"]
OTHER_OPTIONS = dict(top_k=3, pose_top_k=2, use_inverted_file=True, inverted_file_words=2, min_margin=-0.5,
                     ransac_iterations=300, max_reprojection_error_px=6.0, min_inliers=8, seed=5)


@pytest.fixture(scope="session")
def tiny(tmp_path_factory):
    lboost, tiny_dir = os.environ.get("LMB_LBOOST"), os.environ.get("LMB_TINY_DIR")
    if not lboost or not tiny_dir or not (Path(tiny_dir) / "map.h5").exists():
        pytest.skip("LMB_LBOOST and LMB_TINY_DIR (the tiny world of the ctest fixture lmb_tiny_world) "
                    "are not available")
    tiny_dir = Path(tiny_dir)
    work = tmp_path_factory.mktemp("tiny")
    t = SimpleNamespace(dir=tiny_dir, map=tiny_dir / "map.h5", collection=tiny_dir / "collection",
                        work=work, vocab=work / "vocab.lbv", run=work / "run", model=work / "model.lbm",
                        poses=work / "poses.json", poses_other=work / "poses_other.json",
                        report=work / "report.json")
    run_lboost("vocab", "--images", t.collection / "images", "--out", t.vocab, "--words", 16, "--seed", 7)
    run_lboost("train", "--map", t.map, "--vocab", t.vocab, "--out", t.run, "--rounds", 20,
               "--dims-per-round", 100, "--threads", 2)
    run_lboost("export", "--run", t.run, "--map", t.map, "--vocab", t.vocab, "--out", t.model)
    run_lboost("localize", "--model", t.model, "--map", t.map, "--out", t.poses, "--all-matches")
    run_lboost("localize", "--model", t.model, "--map", t.map, "--out", t.poses_other, "--all-matches",
               "--threads", 2, *OTHER_FLAGS)
    run_lboost("eval", "--model", t.model, "--map", t.map, "--run", t.run, "--vocab", t.vocab, "--report", t.report,
               "--methods", "landmarkboost,hamming_ratio")
    return t
