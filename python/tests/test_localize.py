"""landmarkboost: models, cameras, options and localization against `lboost localize`."""
import json
import os
import subprocess
import sys
import threading

import numpy as np
import pytest

import landmarkboost as lb
from conftest import OTHER_OPTIONS


def query_frames(m):
    return [(f, m.frames[f]) for f in m.query_frames]


def localize_frame(localizer, m, f, options=None):
    frame = m.frames[f]
    return localizer.localize(m.cameras[frame.camera], m.frame_keypoints(f), m.frame_descriptors(f),
                              frame.gravity_in_cam, options)


def match_rows(r):
    """[keypoint, rank, landmark, score, inlier] of every match, as `lboost localize --all-matches`."""
    inlier = np.zeros(r.num_matches, dtype=bool)
    inlier[r.correspondence_match[r.inlier_mask]] = True
    return [[int(k), int(j), int(l), float(s), bool(i)] for k, j, l, s, i in
            zip(r.match_keypoint, r.match_rank, r.match_landmark, r.match_score, inlier)]


@pytest.mark.parametrize("which", ["default", "other"])
def test_localize_equals_lboost_localize_bit_for_bit(tiny, which):
    m = lb.io.read_map(tiny.map)
    if which == "default":
        localizer, path = lb.Localizer(lb.load(tiny.model)), tiny.poses
    else:
        localizer, path = lb.Localizer(lb.load(tiny.model), lb.LocalizerOptions(**OTHER_OPTIONS)), tiny.poses_other
    expected = json.loads(path.read_text())["frames"]
    frames = query_frames(m)
    assert len(frames) == len(expected) > 0
    localized = 0
    for (f, frame), e in zip(frames, expected):
        r = localize_frame(localizer, m, f)
        assert frame.name == e["name"]
        assert r.success == e["success"], frame.name
        assert r.pose_found == e["pose_found"] and r.confidence == e["confidence"], frame.name
        assert r.calibrated == lb.load(tiny.model).calibrated
        localized += r.success
        q, t = r.cam_from_world.rotation, r.cam_from_world.translation
        pose = e["cam_from_world"]
        # Exact: JSON's shortest round-trip decimals parse back to the same doubles.
        assert [pose["qw"], pose["qx"], pose["qy"], pose["qz"]] == q.tolist(), frame.name
        assert [pose["tx"], pose["ty"], pose["tz"]] == t.tolist(), frame.name
        assert r.num_inliers == e["num_inliers"]
        assert len(r.correspondence_match) == e["num_correspondences"]
        assert match_rows(r) == e["matches"], frame.name
    assert localized > 0  # the comparison covers poses, not only failures


def test_result_arrays_are_consistent_read_only_views(tiny):
    m = lb.io.read_map(tiny.map)
    model = lb.load(tiny.model)
    f = m.query_frames[0]
    r = localize_frame(lb.Localizer(model, lb.LocalizerOptions(top_k=3, pose_top_k=2)), m, f)
    n = m.frames[f].num_keypoints
    assert r.num_keypoints == n and r.match_begin.shape == (n + 1,) and r.match_begin[0] == 0
    assert r.match_begin[-1] == r.num_matches
    counts = np.diff(r.match_begin)
    assert counts.max() <= 3
    assert np.array_equal(r.match_keypoint, np.repeat(np.arange(n), counts))
    for k in range(n):
        rows = slice(r.match_begin[k], r.match_begin[k + 1])
        assert np.array_equal(r.match_rank[rows], np.arange(counts[k]))
        assert np.all(np.diff(r.match_score[rows]) <= 0)  # best first
        assert np.all(r.match_score[rows] > r.match_background_score[rows])  # min_margin 0
    # Classes and landmarks agree with the model's table.
    assert np.array_equal(model.class_landmarks[r.match_class], r.match_landmark)
    # Correspondences: each keypoint's best two matches.
    assert np.array_equal(r.match_keypoint[r.correspondence_match], r.correspondence_keypoint)
    assert np.all(r.match_rank[r.correspondence_match] < 2)
    assert r.inlier_mask.dtype == bool and r.inlier_mask.sum() == r.num_inliers
    for a in (r.match_begin, r.match_class, r.match_landmark, r.match_score, r.correspondence_match, r.inlier_mask):
        assert not a.flags.writeable
        assert a.base is not None  # a view into the result, not a copy
    # Views keep the result alive.
    scores = r.match_score
    copy = scores.copy()
    del r
    assert np.array_equal(scores, copy)


def test_descriptor_layouts_and_dtypes_give_the_same_result(tiny):
    m = lb.io.read_map(tiny.map)
    localizer = lb.Localizer(lb.load(tiny.model))
    f = m.query_frames[0]
    frame = m.frames[f]
    camera, kp, desc = m.cameras[frame.camera], m.frame_keypoints(f), m.frame_descriptors(f)
    base = localizer.localize(camera, kp, desc, frame.gravity_in_cam)
    # Fortran-order descriptors (copied), float64 keypoints (converted), a list for gravity.
    other = localizer.localize(camera, kp.astype(np.float64), np.asfortranarray(desc),
                               list(frame.gravity_in_cam * 3.0))
    assert other.cam_from_world.rotation.tolist() == base.cam_from_world.rotation.tolist()
    assert match_rows(other) == match_rows(base)
    # Zero keypoints: no pose, no error.
    empty = localizer.localize(camera, np.zeros((0, 4), np.float32), np.zeros((0, 64), np.uint8), [0, 1, 0])
    assert not empty.success and empty.num_matches == 0 and empty.match_begin.tolist() == [0]


def test_bad_input_raises_one_clear_error(tiny):
    m = lb.io.read_map(tiny.map)
    localizer = lb.Localizer(lb.load(tiny.model))
    f = m.query_frames[0]
    frame = m.frames[f]
    camera, kp, desc = m.cameras[frame.camera], m.frame_keypoints(f), m.frame_descriptors(f)
    g = frame.gravity_in_cam
    with pytest.raises(ValueError, match=r"keypoints: expected an \(n, 4\) array .* got a float32 array of shape"):
        localizer.localize(camera, kp[:, :2], desc, g)
    with pytest.raises(ValueError, match=r"descriptors: expected a uint8 array of shape \(%d, 64\)" % len(kp)):
        localizer.localize(camera, kp, desc[:, :32], g)
    with pytest.raises(ValueError, match="descriptors: .* got a int64 array"):
        localizer.localize(camera, kp, desc.astype(np.int64), g)
    with pytest.raises(lb.Error, match="gravity"):
        localizer.localize(camera, kp, desc, [0, 0, 0])
    bad = kp.copy()
    bad[3, 2] = -1.0
    with pytest.raises(lb.Error, match="localize"):
        localizer.localize(camera, bad, desc, g)
    with pytest.raises(lb.Error, match="top_k"):
        localizer.localize(camera, kp, desc, g, lb.LocalizerOptions(top_k=2, pose_top_k=3))


def test_threads_localize_in_parallel_with_the_gil_released(tiny):
    m = lb.io.read_map(tiny.map)
    localizer = lb.Localizer(lb.load(tiny.model))
    frames = [f for f, _ in query_frames(m)]
    serial = {f: match_rows(localize_frame(localizer, m, f)) for f in frames}
    before = lb._core._calls_without_gil()
    results, errors = {}, []

    def work(mine):
        try:
            for f in mine:
                results[f] = match_rows(localize_frame(localizer, m, f))
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(frames[i::4],)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert results == serial
    # Every call ran its C++ part without holding the GIL.
    assert lb._core._calls_without_gil() - before == len(frames)


def test_model_camera_pose_and_options(tiny):
    model = lb.load(tiny.model)
    assert model.descriptor_bytes == 64 and model.num_words == 16 and model.detector == "BRISK"
    assert model.class_landmarks.shape == (model.num_classes,)
    assert model.class_positions.shape == (model.num_classes, 3)
    m = lb.io.read_map(tiny.map)
    # Exported class positions are the map's landmark positions.
    assert np.array_equal(model.class_positions, m.landmark_positions[model.class_landmarks])
    assert lb.Model.from_bytes(tiny.model.read_bytes()).num_classes == model.num_classes
    assert "classes" in repr(model)

    cam = lb.Camera("SIMPLE_RADIAL", 640, 480, [500.0, 320.0, 240.0, 0.01])
    assert (cam.model, cam.width, cam.height, cam.params) == ("SIMPLE_RADIAL", 640, 480, [500.0, 320.0, 240.0, 0.01])
    assert lb.Camera(0, 10, 10, [5, 5, 5]).model == "SIMPLE_PINHOLE"
    # project: a point on the optical axis lands on the principal point (COLMAP's convention).
    assert np.allclose(cam.project([[0.0, 0.0, 2.0], [0.0, 0.0, -1.0]])[0], [320.0, 240.0])
    assert np.all(np.isnan(cam.project([[0.0, 0.0, -1.0]])))
    with pytest.raises(lb.Error, match="Camera"):
        lb.Camera("PINHOLE", 640, 480, [500.0, 320.0, 240.0])
    with pytest.raises(lb.Error, match="OPENCV_FISHEYE|model"):
        lb.Camera("OPENCV_FISHEYE", 640, 480, [1, 1, 1, 1, 0, 0, 0, 0])

    pose = lb.Rigid3d([np.cos(0.3), 0, np.sin(0.3), 0], [1.0, 2.0, 3.0])
    x = np.array([0.5, -1.0, 2.0])
    assert np.allclose(pose.matrix() @ np.append(x, 1.0), pose * x)
    assert np.allclose((pose.inverse() * pose).matrix(), np.hstack([np.eye(3), np.zeros((3, 1))]))
    assert np.allclose(pose * pose.center(), 0.0)
    assert np.allclose(lb.Rigid3d.from_matrix(pose.matrix()).rotation, pose.rotation)
    with pytest.raises(lb.Error, match="unit quaternion"):
        lb.Rigid3d([1, 1, 0, 0], [0, 0, 0])

    o = lb.LocalizerOptions(top_k=4, seed=9)
    assert (o.top_k, o.seed, o.pose_top_k, o.min_margin, o.ransac_iterations) == (4, 9, 1, 0.0, 500)
    o.min_margin = float("-inf")
    assert o.min_margin == float("-inf")
    with pytest.raises(TypeError, match="unknown option 'topk'"):
        lb.LocalizerOptions(topk=3)
    with pytest.raises(lb.Error, match="top_k"):
        lb.LocalizerOptions(top_k=0)
    assert lb.Localizer(model, o).options.top_k == 4


def test_load_errors_name_the_file(tmp_path):
    with pytest.raises(lb.Error, match="missing.lbm"):
        lb.load(tmp_path / "missing.lbm")
    (tmp_path / "x.lbm").write_bytes(b"NOTAMODEL" * 10)
    with pytest.raises(lb.Error, match=r"x.lbm: neither a LandmarkBoost model"):
        lb.load(tmp_path / "x.lbm")
    with pytest.raises(lb.Error, match="x.lbm"):
        lb.Model.load(tmp_path / "x.lbm")
    assert issubclass(lb.Error, RuntimeError)


def test_localizing_loads_neither_hdf5_nor_opencv(tiny, tmp_path):
    """The core module is what an app that localizes loads: no HDF5, no OpenCV, no MPI."""
    m = lb.io.read_map(tiny.map)
    f = m.query_frames[0]
    frame = m.frames[f]
    np.savez(tmp_path / "frame.npz", keypoints=m.frame_keypoints(f), descriptors=m.frame_descriptors(f),
             gravity=frame.gravity_in_cam)
    cam = m.cameras[frame.camera]
    script = f"""
import numpy as np, landmarkboost as lb
d = np.load({str(tmp_path / 'frame.npz')!r})
cam = lb.Camera({cam.model!r}, {cam.width}, {cam.height}, {cam.params!r})
r = lb.Localizer(lb.load({str(tiny.model)!r})).localize(cam, d['keypoints'], d['descriptors'], d['gravity'])
maps = open('/proc/self/maps').read()
print(r.num_matches, [n for n in ('hdf5', 'opencv', 'mpi') if n in maps])
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=os.environ, check=True)
    count, loaded = out.stdout.split(" ", 1)
    assert int(count) > 0
    assert loaded.strip() == "[]", out.stdout


def test_walk_tracker_reports_what_the_frame_rule_reports_and_more(tiny):
    model = lb.load(tiny.model)
    if not model.calibrated:
        with pytest.raises(lb.Error, match="no pose calibration"):
            lb.WalkTracker(model)
        return
    m = lb.io.read_map(tiny.map)
    localizer, tracker = lb.Localizer(model), lb.WalkTracker(model)
    assert tracker.last_trusted is None
    for i, (f, frame) in enumerate(query_frames(m)):
        r = localize_frame(localizer, m, f)
        v = tracker.update(r)
        # The frame rule's verdict is kept unless the pose disagrees with the frame before; the walk
        # rule may add a pose that continues the walk.
        refused = v["agreement_applies"] and v["agrees"] is False
        assert v["localized"] == ((r.success or v["by_walk"]) and not refused), frame.name
        if i == 0:
            assert v["agrees"] is None
        assert v["frame_confidence"] == (r.confidence if r.pose_found else 0.0), frame.name
        if i == 0:
            assert not v["continues"]
        if not model.walk_calibrated:
            assert not v["continues"] and not v["by_walk"]
        if v["localized"]:
            assert tracker.last_trusted is not None
            assert tracker.last_trusted.translation.tolist() == r.cam_from_world.translation.tolist()
    tracker.reset()
    assert tracker.last_trusted is None
