"""landmarkboost.io: map.h5 and report.json."""
import json
import math

import numpy as np
import pytest

import landmarkboost as lb
from landmarkboost import io


def test_read_map_columns_are_views_with_the_right_layout(tiny):
    m = io.read_map(tiny.map)
    assert m.detector == "BRISK" and m.descriptor_bytes == 64
    n, frames = m.num_keypoints, m.frames
    assert m.keypoints.shape == (n, 4) and m.keypoints.dtype == np.float32
    assert m.descriptors.shape == (n, 64) and m.descriptors.dtype == np.uint8
    assert m.keypoint_landmark.shape == (n,)
    assert m.landmark_positions.shape == (m.num_landmarks, 3)
    assert 0 < len(m.query_frames) < m.num_frames == len(frames)
    assert all(frames[f].is_query for f in m.query_frames)
    # Frames hold their keypoints in order, covering all of them.
    assert frames[0].first_keypoint == 0
    assert sum(f.num_keypoints for f in frames) == n
    for i, f in enumerate(frames):
        rows = slice(f.first_keypoint, f.first_keypoint + f.num_keypoints)
        assert np.array_equal(m.frame_keypoints(i), m.keypoints[rows])
        assert np.array_equal(m.frame_descriptors(i), m.descriptors[rows])
        assert np.array_equal(m.frame_keypoint_landmarks(i), m.keypoint_landmark[rows])
        assert abs(np.linalg.norm(f.gravity_in_cam) - 1.0) < 1e-9
        assert f.camera < len(m.cameras)
    # Landmark columns (strided views into the records) against counts recomputed from the
    # keypoints: map and query observations of each landmark.
    is_query = np.zeros(n, dtype=bool)
    for f in m.query_frames:
        is_query[frames[f].first_keypoint:frames[f].first_keypoint + frames[f].num_keypoints] = True
    with_landmark = m.keypoint_landmark >= 0
    map_obs = np.bincount(m.keypoint_landmark[with_landmark & ~is_query], minlength=m.num_landmarks)
    query_obs = np.bincount(m.keypoint_landmark[with_landmark & is_query], minlength=m.num_landmarks)
    assert np.array_equal(m.landmark_map_observations, map_obs)
    assert np.array_equal(m.landmark_query_observations, query_obs)
    assert np.all(m.landmark_map_observations >= 3)
    assert np.all(np.isfinite(m.landmark_positions))
    assert np.all(m.landmark_mean_reprojection_error >= 0) and np.all(m.landmark_quality > 0)
    for a in (m.keypoints, m.descriptors, m.landmark_positions, m.landmark_quality):
        assert not a.flags.writeable and a.base is not None
    # The camera is what the rendered world wrote (a lens with distortion).
    assert m.cameras[0].model == "OPENCV"
    # A frame's ground-truth pose projects its keypoints' landmarks onto the keypoints.
    f = m.query_frames[0]
    frame = frames[f]
    kp, lm = m.frame_keypoints(f), m.frame_keypoint_landmarks(f)
    seen = np.flatnonzero(lm >= 0)
    points = np.array([frame.cam_from_world * m.landmark_positions[lm[k]] for k in seen])
    errors = np.linalg.norm(m.cameras[frame.camera].project(points) - kp[seen, :2], axis=1)
    assert len(errors) > 10 and np.median(errors) < 2.0
    with pytest.raises(IndexError, match="out of range"):
        m.frame_keypoints(m.num_frames)


def test_read_map_errors_name_the_file(tmp_path):
    with pytest.raises(lb.Error, match="nothere.h5"):
        io.read_map(tmp_path / "nothere.h5")
    (tmp_path / "bad.h5").write_text("not hdf5")
    with pytest.raises(lb.Error, match="bad.h5"):
        io.read_map(tmp_path / "bad.h5")


def test_read_report_of_lboost_eval(tiny):
    report = lb.read_report(tiny.report)
    raw = json.loads(tiny.report.read_text())
    m = io.read_map(tiny.map)
    assert report.dataset.query_frames == len(m.query_frames)
    assert report.dataset.map_frames == m.num_frames - len(m.query_frames)
    assert set(report.methods) == set(raw["methods"]) and "landmarkboost" in report.methods
    for name, method in report.methods.items():
        assert 0.0 <= method.precision_at_1 <= 1.0, name
        assert method.precision_at_1 == raw["methods"][name]["precision_at_1"]
        per_frame = method.per_frame
        assert len(per_frame.localized) == report.dataset.query_frames
        assert per_frame.localized.dtype == np.int64
        assert per_frame.position_error_m.dtype == np.float64
    assert report.raw == raw and "landmarkboost" in repr(report)
    with pytest.raises(AttributeError, match="no field 'nope'"):
        report.dataset.nope


def test_read_report_non_finite_numbers_and_errors(tmp_path):
    p = tmp_path / "report.json"
    p.write_text(json.dumps({
        "options": {"min_margin": "-inf", "name": "x"},
        "dataset": {"query_frames": 2},
        "methods": {"m": {"precision_at_1": 0.5, "median_position_error_m": None,
                          "miss_rate_at_fppi": {"0.1": 0.2},
                          "per_frame": {"position_error_m": [0.1, None], "localized": [1, 0]}}}}))
    r = lb.read_report(p)
    assert r.options.min_margin == -math.inf and r.options.name == "x"
    m = r.methods["m"]
    assert m.median_position_error_m is None
    assert m.miss_rate_at_fppi["0.1"] == 0.2
    e = m.per_frame.position_error_m
    assert e[0] == 0.1 and math.isnan(e[1])
    assert m.per_frame.localized.tolist() == [1, 0]
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ValueError, match="bad.json: invalid JSON"):
        lb.read_report(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text("[]")
    with pytest.raises(ValueError, match="other.json: not a LandmarkBoost report"):
        lb.read_report(tmp_path / "other.json")
