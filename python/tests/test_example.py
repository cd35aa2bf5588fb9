"""The example scripts on the tiny world: python/examples/localize_queries.py (a map's query frames),
python/examples/localize_image.py (one image file) and python/examples/track_queries.py (a bundle
tracking the query frames), against `lboost localize`."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from PIL import Image

import landmarkboost as lb
from conftest import run_lboost
from test_bundle import write_bundle

EXAMPLES = Path(os.environ.get("LMB_SOURCE_DIR", Path(__file__).parents[2])) / "python" / "examples"


def run_example(script, *args):
    return subprocess.run([sys.executable, str(EXAMPLES / script), *map(str, args)], capture_output=True,
                          text=True)


def test_localize_queries_localizes_the_tiny_worlds_query_frames(tiny):
    r = run_example("localize_queries.py", "--model", tiny.model, "--map", tiny.map, "--threads", 2)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().split("\n")
    expected = json.loads(tiny.poses.read_text())
    frames = expected["frames"]
    assert len(lines) == len(frames) + 1
    for line, frame in zip(lines, frames):
        assert line.startswith(frame["name"] + (": localized" if frame["success"] else ": not localized")), line
        if frame["success"]:
            assert f"error {frame['position_error_m']:.3f} m {frame['rotation_error_deg']:.2f} deg" in line, line
    summary = expected["summary"]
    assert lines[-1].startswith(f"localized {summary['localized']}/{summary['frames']} query frames"), lines[-1]


def test_localize_image_localizes_a_query_image_file_as_lboost_localize(tiny):
    """The image file's BRISK features are the map's (test_cv), so the pose is `lboost localize`'s."""
    m = lb.io.read_map(tiny.map)
    expected = {f["name"]: f for f in json.loads(tiny.poses.read_text())["frames"]}
    checked = 0
    for f in m.query_frames:
        frame = m.frames[f]
        e = expected[frame.name]
        if not e["success"]:
            continue
        image = tiny.collection / "images" / frame.name
        r = run_example("localize_image.py", "--model", tiny.model, "--map", tiny.map, "--image", image,
                        "--gravity", *frame.gravity_in_cam)
        assert r.returncode == 0, r.stdout + r.stderr
        assert f"{image}: {frame.num_keypoints} keypoints" in r.stdout, r.stdout
        assert f"{image}: localized with {e['num_inliers']} inliers" in r.stdout, r.stdout
        p = e["cam_from_world"]
        pose = lb.Rigid3d([p["qw"], p["qx"], p["qy"], p["qz"]], [p["tx"], p["ty"], p["tz"]])
        centre = r.stdout.split("camera centre in the map [")[1].split("]")[0].split()
        assert np.allclose([float(v) for v in centre], pose.center(), atol=1e-4), r.stdout
        checked += 1
        if checked == 2:
            break
    assert checked == 2


def test_localize_image_refuses_and_fails_clearly(tiny, tmp_path):
    m = lb.io.read_map(tiny.map)
    camera = m.cameras[0]
    # A featureless image of the camera's size: not localized, exit code 1.
    blank = tmp_path / "blank.png"
    Image.fromarray(np.full((camera.height, camera.width), 128, np.uint8)).save(blank)
    r = run_example("localize_image.py", "--model", tiny.model, "--map", tiny.map, "--image", blank,
                    "--gravity", 0, 1, 0)
    assert r.returncode == 1 and f"{blank}: not localized" in r.stdout, r.stdout + r.stderr
    # An image of another size than the camera's: one line naming both.
    small = tmp_path / "small.png"
    Image.fromarray(np.zeros((10, 20), np.uint8)).save(small)
    r = run_example("localize_image.py", "--model", tiny.model, "--map", tiny.map, "--image", small,
                    "--gravity", 0, 1, 0)
    assert r.returncode == 1
    assert r.stderr.strip() == f"{small}: 20x10 pixels, the camera is {camera.width}x{camera.height}"
    # A missing file: one line naming it.
    r = run_example("localize_image.py", "--model", tiny.model, "--map", tiny.map, "--image", tmp_path / "no.png",
                    "--gravity", 0, 1, 0)
    assert r.returncode == 1
    assert r.stderr.strip().startswith(f"{tmp_path / 'no.png'}: cannot read the image"), r.stderr


def test_track_queries_tracks_as_lboost_localize_track(tiny, tmp_path):
    """Two areas (copies of the tiny model, split along x) tracked with a radius that holds the
    world: the example's frames, areas and tracked flags are `lboost localize --bundle --track`'s."""
    index = write_bundle(tmp_path / "bundle", tiny.model, [("-inf", "0"), ("0", "inf")], reach=1000.0)
    r = run_example("track_queries.py", "--bundle", index, "--map", tiny.map, "--radius", 100)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().split("\n")
    run_lboost("localize", "--bundle", index, "--map", tiny.map, "--track", 100, "--out", tmp_path / "track.json")
    frames = json.loads((tmp_path / "track.json").read_text())["modes"][0]["frames"]
    assert len(lines) == len(frames) + 1
    for line, frame in zip(lines, frames):
        how = "tracked" if frame["tracked"] else ("relocalized" if frame["relocalized"] else "not tracked")
        assert line.startswith(f"{frame['name']}: {how}"), line
        if frame["success"]:
            assert f"area {frame['area']} of {frame['areas_scored']} scored" in line, line
            assert f"error {frame['position_error_m']:.3f} m" in line, line
            assert (", localized," if frame["localized"] else ", not localized,") in line, line
    tracked = sum(f["tracked"] for f in frames)
    assert tracked > 0 and lines[-1].startswith(f"tracked {tracked}/{len(frames)} query frames"), lines[-1]
