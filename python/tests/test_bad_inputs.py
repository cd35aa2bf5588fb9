"""Arguments of the wrong type or value: one clear exception naming the argument, never a crash, a
pybind11 "Unable to cast" message, a file descriptor taken for a path, or a RecursionError."""
import os
import zlib
from pathlib import Path

import numpy as np
import pytest

import landmarkboost as lb
import landmarkboost.cv  # noqa: F401
import landmarkboost.io  # noqa: F401


def path_functions():
    return {"load": lb.load, "read_report": lb.read_report, "io.read_report": lb.io.read_report,
            "io.read_map": lb.io.read_map, "Model.load": lb.Model.load, "AreaBundle.open": lb.AreaBundle.open,
            "cv.read_image": lb.cv.read_image}


@pytest.mark.parametrize("name", sorted(path_functions()))
def test_paths_are_str_bytes_or_pathlike_never_a_file_descriptor(name, tmp_path):
    fn = path_functions()[name]
    r, w = os.pipe()
    try:
        os.write(w, b"LMBMODEL and more")
        os.close(w)
        for bad in (r, 2.5, None, True, ["x"]):
            with pytest.raises(TypeError, match="path") as e:
                fn(bad)
            assert "Unable to cast" not in str(e.value)
        # The descriptor was neither read nor closed.
        assert os.read(r, 100) == b"LMBMODEL and more"
    finally:
        os.close(r)
    # A NUL in the path: an error, not a shorter path.
    with pytest.raises((ValueError, TypeError)):
        fn(str(tmp_path / "x.lbm") + "\0.txt")


def test_paths_as_bytes_and_pathlike_work(tmp_path):
    (tmp_path / "r.json").write_text('{"methods": {}}')
    assert lb.read_report(os.fsencode(tmp_path / "r.json")).methods == {}
    assert lb.read_report(tmp_path / "r.json").path == str(tmp_path / "r.json")
    with pytest.raises(lb.Error, match="missing.lbm: cannot open"):
        lb.load(os.fsencode(tmp_path / "missing.lbm"))
    with pytest.raises(lb.Error, match="missing.png"):
        lb.cv.read_image(Path(tmp_path / "missing.png"))


def test_option_values_name_the_option_and_its_range():
    cases = [
        (dict(seed=-1), lb.Error, r"seed = -1: must be an integer in 0\.\.9223372036854775807"),
        (dict(seed=2**63), lb.Error, r"seed = 9223372036854775808: must be an integer in 0\.\."),
        (dict(top_k=2**40), lb.Error, r"top_k = 1099511627776: must be an integer in 1\.\.1000000"),
        (dict(top_k=0), lb.Error, r"top_k = 0: must be an integer in 1\.\.1000000"),
        (dict(inverted_file_words=300), lb.Error, r"inverted_file_words = 300: must be an integer in 1\.\.256"),
        (dict(min_inliers=3), lb.Error, r"min_inliers = 3: must be an integer in 4\.\."),
        (dict(ransac_iterations=-5), lb.Error, r"ransac_iterations = -5: must be an integer in 1\.\."),
        (dict(top_k=2.5), TypeError, r"top_k: expected an integer in 1\.\.1000000; got 2.5 \(float\)"),
        (dict(top_k="3"), TypeError, r"top_k: expected an integer"),
        (dict(top_k=True), TypeError, r"top_k: expected an integer .* \(bool\)"),
        (dict(use_inverted_file="no"), TypeError, r"use_inverted_file: expected True or False; got 'no' \(str\)"),
        (dict(refine=1), TypeError, r"refine: expected True or False"),
        (dict(min_margin="x"), TypeError, r"min_margin: expected a real number; got 'x' \(str\)"),
        (dict(min_margin=1j), TypeError, r"min_margin: expected a real number"),
        (dict(min_margin=False), TypeError, r"min_margin: expected a real number"),
        (dict(max_reprojection_error_px=10**400), lb.Error, r"max_reprojection_error_px = .*range of a double"),
    ]
    for kwargs, error, message in cases:
        with pytest.raises(error, match="LocalizerOptions: " + message) as e:
            lb.LocalizerOptions(**kwargs)
        assert "Unable to cast" not in str(e.value), kwargs
    # Setting an attribute converts the same way.
    o = lb.LocalizerOptions()
    with pytest.raises(lb.Error, match=r"LocalizerOptions: seed = -1: must be an integer in 0\.\."):
        o.seed = -1
    with pytest.raises(TypeError, match="LocalizerOptions: prosac: expected True or False"):
        o.prosac = None
    # numpy scalars of the right kind are numbers like any other.
    o = lb.LocalizerOptions(top_k=np.int64(3), seed=np.uint64(2**63 - 1), min_margin=np.float32(-0.5),
                            refine=np.bool_(False), max_reprojection_error_px=8)
    assert (o.top_k, o.seed, o.min_margin, o.refine, o.max_reprojection_error_px) == (3, 2**63 - 1, -0.5, False, 8.0)


def test_camera_model_of_the_wrong_type_names_the_argument():
    for bad in (None, 1.5, True):
        with pytest.raises(TypeError, match=r"Camera: model: expected a model name \(str\) or a COLMAP model id"):
            lb.Camera(bad, 640, 480, [500.0, 500.0, 320.0, 240.0])
    with pytest.raises(lb.Error, match="Camera: model = 1099511627776"):
        lb.Camera(2**40, 640, 480, [500.0, 500.0, 320.0, 240.0])
    assert lb.Camera(np.int32(1), 640, 480, [500.0, 500.0, 320.0, 240.0]).model == "PINHOLE"


def write_index(path, area="bytes 10 crc32 00000000 landmarks 3", cell="-1 -1 -1 1 1 1"):
    """A one-area bundle index, area-0.lbm beside it; selecting areas reads no model."""
    path.write_text(f"lmb-bundle 1\nreach 1.0\nareas 1\narea 0 file area-0.lbm {area} cell {cell}\n")
    return path


def test_a_prior_of_the_wrong_shape_names_the_prior(tmp_path):
    bundle = lb.AreaBundle.open(write_index(tmp_path / "bundle.txt"))
    assert bundle.select(((0.0, 0.0, 0.0), 1.0)) == [0]
    assert bundle.select([np.zeros(3, np.float32), np.float64(1.0)]) == [0]  # a list, numpy values
    assert bundle.select((np.array([50, 0, 0]), 2)) == []  # integers
    cases = [
        (((0.0, 1.0), 5.0), ValueError, r"prior: position: expected 3 real numbers .* float64 array of shape \(2,\)"),
        ((np.zeros((3, 1)), 5.0), ValueError, r"prior: position: expected 3 real numbers .* shape \(3, 1\)"),
        ((np.zeros(3, complex), 5.0), ValueError, r"prior: position: .* got a complex128 array"),
        ((np.zeros(3, bool), 5.0), ValueError, r"prior: position: .* got a bool array"),
        ((("a", "b", "c"), 5.0), ValueError, r"prior: position: .* got a <U1 array"),
        (((0.0, 0.0, 0.0), "5"), TypeError, r"prior: radius: expected a real number; got '5' \(str\)"),
        (((0.0, 0.0, 0.0), 1j), TypeError, r"prior: radius: expected a real number"),
        (((0.0, 0.0, 0.0),), ValueError, r"prior: expected \(position, radius\) or None"),
        ("ab", ValueError, r"prior: expected \(position, radius\) or None; got 'ab' \(str\)"),
        (5.0, ValueError, r"prior: expected \(position, radius\) or None"),
    ]
    for prior, error, message in cases:
        with pytest.raises(error, match=message) as e:
            bundle.select(prior)
        assert "Unable to cast" not in str(e.value), prior
    with pytest.raises(lb.Error, match="not finite"):
        bundle.select(((np.inf, 0.0, 0.0), 1.0))


def bad_keypoint_cases(kp):
    """(keypoints, error, message) of real-number, finiteness and range violations."""
    def with_value(row, col, value, dtype=np.float64):
        k = kp.astype(dtype)
        k[row, col] = value
        return k

    return [
        (kp.astype(np.complex128), ValueError, r"keypoints: expected real numbers .* got a complex128 array"),
        (kp.astype(bool), ValueError, r"keypoints: expected real numbers .* got a bool array"),
        (kp.astype(object), ValueError, r"keypoints: expected real numbers .* got a object array"),
        (with_value(2, 3, np.nan), lb.Error, r"keypoints: row 2 \(x, y, size, angle\) = \(.*, nan\)"),
        (with_value(2, 3, 1e30), lb.Error, r"keypoints: row 2 .*angle degrees in \[-360, 360\]"),
        (with_value(2, 3, -np.inf), lb.Error, r"keypoints: row 2 .*angle"),
        (with_value(4, 0, np.nan), lb.Error, r"keypoints: row 4 .*x and y must be finite"),
        (with_value(4, 1, 1e39), lb.Error, r"keypoints: row 4 \(x, y, size, angle\) = \(.*, inf, "),
        (with_value(4, 2, 0.0), lb.Error, r"keypoints: row 4 .*size finite and > 0"),
        (with_value(4, 2, 1e-50), lb.Error, r"keypoints: row 4 .*size finite and > 0"),
    ]


def test_keypoints_are_finite_real_numbers(tiny, tmp_path):
    m = lb.io.read_map(tiny.map)
    f = m.query_frames[0]
    frame = m.frames[f]
    camera, kp, desc, g = m.cameras[frame.camera], m.frame_keypoints(f), m.frame_descriptors(f), frame.gravity_in_cam
    localizer = lb.Localizer(lb.load(tiny.model))
    data = tiny.model.read_bytes()
    (tmp_path / "area-0.lbm").write_bytes(data)
    area = f"bytes {len(data)} crc32 {zlib.crc32(data):08x} landmarks {lb.load(tiny.model).num_classes}"
    index = write_index(tmp_path / "bundle.txt", area=area, cell="-inf -inf -inf inf inf inf")
    bundle_localizer = lb.BundleLocalizer(lb.load(index))
    for keypoints, error, message in bad_keypoint_cases(kp):
        with pytest.raises(error, match="localize: " + message), np.errstate(over="ignore"):
            localizer.localize(camera, keypoints, desc, g)
        with pytest.raises(error, match="localize: " + message), np.errstate(over="ignore"):
            bundle_localizer.localize(camera, keypoints, desc, g)
    # Valid inputs of other real dtypes and angles: the same frame.
    base = localizer.localize(camera, kp, desc, g)
    assert localizer.localize(camera, kp.astype(np.float64), desc, g).num_matches == base.num_matches
    no_angle = kp.copy()
    no_angle[:, 3] = -1.0
    assert localizer.localize(camera, no_angle, desc, g).num_keypoints == len(kp)
    integers = np.rint(kp).astype(np.int64)
    integers[:, 2] = np.maximum(integers[:, 2], 1)
    assert localizer.localize(camera, integers, desc, g).num_keypoints == len(kp)


def test_read_report_names_the_file_for_any_damage(tmp_path):
    def damaged(name, data):
        p = tmp_path / name
        p.write_bytes(data)
        return p

    cases = [
        (damaged("deep.json", b"[" * 100000), r"deep.json: invalid JSON: nested too deeply"),
        # Deep enough for the conversion into Records and arrays if not for the JSON parser.
        (damaged("deep2.json", b'{"methods": {}, "x": ' + b"[" * 900 + b"]" * 900 + b"}"),
         r"deep2.json: (invalid JSON: )?nested too deeply"),
        (damaged("latin1.json", '{"methods": {"é": 1}}'.encode("latin-1")), r"latin1.json: not UTF-8 text \(byte 14"),
        (damaged("digits.json", b'{"methods": {}, "n": ' + b"7" * 5000 + b"}"), r"digits.json: invalid JSON"),
        (damaged("truncated.json", b'{"methods": {"a": [1, 2'), r"truncated.json: invalid JSON"),
        (damaged("list.json", b"[1, 2]"), r"list.json: not a LandmarkBoost report"),
    ]
    for path, message in cases:
        with pytest.raises(lb.Error, match=message) as e:
            lb.read_report(path)
        assert isinstance(e.value, ValueError)  # as documented before: invalid JSON is a ValueError
    # Integers beyond int64 (and float64) are read, not an OverflowError.
    r = lb.read_report(damaged("big.json", b'{"methods": {}, "a": [1, 99999999999999999999], "b": [1, '
                                           + b"9" * 400 + b"]}"))
    assert r.a.dtype == np.float64 and r.a[1] == 1e20
    assert r.b == [1, int("9" * 400)]


def test_an_error_quoting_bytes_that_are_not_utf8_keeps_its_message(tmp_path):
    index = write_index(tmp_path / "bundle.txt")
    index.write_bytes(index.read_bytes().replace(b"reach 1.0", b"reach 1\xfc0"))
    with pytest.raises(lb.Error) as e:
        lb.load(index)
    assert str(e.value).startswith(f"{index} line 2: ") and "1\\xfc0" in str(e.value), str(e.value)
