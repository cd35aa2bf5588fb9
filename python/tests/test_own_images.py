"""docs/your_own_images.md's route after COLMAP, end to end on the tiny world's COLMAP model (as a
user's reconstruction: a sparse model and its image folder, no gravity file):
`lboost import colmap --up auto` -> `lboost map` (which must take the imported gravity.txt) ->
`lboost vocab` -> `lboost train` -> `lboost export` -> `lboost localize`, then one query image
localized from its file by python/examples/localize_image.py; poses against the model's own."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

import landmarkboost as lb
from conftest import run_lboost

EXAMPLES = Path(os.environ.get("LMB_SOURCE_DIR", Path(__file__).parents[2])) / "python" / "examples"


def angle_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


def test_import_colmap_up_auto_map_train_localize_an_image(tiny, tmp_path):
    coll, out = tmp_path / "collection", tmp_path
    # first:0.75 over the sorted names keeps the model's own split (30 map/..., then 10 query/...).
    log = run_lboost("import", "colmap", "--sparse", tiny.collection / "sparse", "--images",
                     tiny.collection / "images", "--out", coll, "--split", "first:0.75", "--up", "auto")
    # The estimate of the up axis and its angle to the nearest world axis (the world is z-up).
    found = re.search(r"--up auto: up = \(([-\d.e]+), ([-\d.e]+), ([-\d.e]+)\).*nearest world axis \+z, "
                      r"([\d.]+) deg away", log)
    assert found, log
    up, up_angle = np.array([float(v) for v in found.groups()[:3]]), float(found.group(4))
    assert up_angle < 5 and abs(angle_deg(up, [0, 0, 1]) - up_angle) < 0.1
    assert (coll / "gravity.txt").exists()

    log = run_lboost("map", "--collection", coll, "--out", out / "map.h5", "--threads", 2)
    assert f"map: gravity: per image from {coll / 'gravity.txt'} (found in the collection" in log, log
    m = lb.io.read_map(out / "map.h5")
    reference = lb.io.read_map(tiny.map)  # the same world mapped directly, with --up +z
    assert [f.name for f in m.frames] == ["map/" + f.name if not f.is_query else "query/" + f.name
                                          for f in reference.frames]
    assert list(m.query_frames) == list(reference.query_frames)
    # The same images and poses: the same keypoints, descriptors and landmarks.
    assert np.array_equal(m.keypoints, reference.keypoints)
    assert np.array_equal(m.descriptors, reference.descriptors)
    assert np.array_equal(m.keypoint_landmark, reference.keypoint_landmark)
    # Gravity: -up of the estimate, which is up_angle from the world's +z.
    for f, r in zip(m.frames, reference.frames):
        assert abs(angle_deg(f.gravity_in_cam, r.gravity_in_cam) - up_angle) < 0.1, f.name
        assert np.allclose(f.gravity_in_cam, f.cam_from_world.matrix()[:, :3] @ -up / np.linalg.norm(up), atol=1e-4)

    run_lboost("vocab", "--images", coll / "images", "--out", out / "vocab.lbv", "--words", 16, "--seed", 7)
    run_lboost("train", "--map", out / "map.h5", "--vocab", out / "vocab.lbv", "--out", out / "run",
               "--rounds", 20, "--dims-per-round", 100, "--threads", 2)
    run_lboost("export", "--run", out / "run", "--map", out / "map.h5", "--vocab", out / "vocab.lbv",
               "--out", out / "model.lbm")
    run_lboost("localize", "--model", out / "model.lbm", "--map", out / "map.h5", "--out", out / "poses.json")
    poses = json.loads((out / "poses.json").read_text())["frames"]
    assert [e["name"] for e in poses] == [m.frames[f].name for f in m.query_frames]

    # Each query image from its file, gravity as a device would give it (here: the map's): the
    # image's features are the map's (test_cv), so the example's result is `lboost localize`'s.
    # (A 20-round model of this small world localizes poorly; this checks the route, not accuracy.)
    for f, e in list(zip(m.query_frames, poses))[:3]:
        frame = m.frames[f]
        r = subprocess.run([sys.executable, str(EXAMPLES / "localize_image.py"), "--model", str(out / "model.lbm"),
                            "--map", str(out / "map.h5"), "--image", str(coll / "images" / frame.name),
                            "--gravity", *map(str, frame.gravity_in_cam)], capture_output=True, text=True)
        assert r.returncode == (0 if e["success"] else 1), r.stdout + r.stderr
        if e["success"]:
            assert f"localized with {e['num_inliers']} inliers" in r.stdout, r.stdout
            p = e["cam_from_world"]
            pose = lb.Rigid3d([p["qw"], p["qx"], p["qy"], p["qz"]], [p["tx"], p["ty"], p["tz"]])
            centre = r.stdout.split("camera centre in the map [")[1].split("]")[0].split()
            assert np.allclose([float(v) for v in centre], pose.center(), atol=1e-4), r.stdout
