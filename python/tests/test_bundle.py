"""landmarkboost.AreaBundle and BundleLocalizer (docs/areas.md) against the single-model Localizer.

The bundles are written here from the tiny world's model (the fixture in conftest.py): an index
(bundle.txt, `lmb-bundle 1`) naming copies of model.lbm as areas, so that a one-area bundle must
give exactly the model's own results.
"""
import shutil
import zlib

import numpy as np
import pytest

import landmarkboost as lb


def write_bundle(folder, model_path, cells, reach=1.0):
    """A bundle of len(cells) copies of model_path; cells: (x_lo, x_hi) of each area along x."""
    folder.mkdir(parents=True, exist_ok=True)
    lines = ["lmb-bundle 1", f"reach {reach!r}", f"areas {len(cells)}"]
    for i, (lo, hi) in enumerate(cells):
        name = f"area-{i}.lbm"
        shutil.copyfile(model_path, folder / name)
        data = (folder / name).read_bytes()
        classes = lb.Model.from_bytes(data).num_classes
        lines.append(f"area {i} file {name} bytes {len(data)} crc32 {zlib.crc32(data):08x} landmarks {classes} "
                     f"cell {lo} -inf -inf {hi} inf inf")
    (folder / "bundle.txt").write_text("\n".join(lines) + "\n")
    return folder / "bundle.txt"


def frame_args(m, f):
    frame = m.frames[f]
    return m.cameras[frame.camera], m.frame_keypoints(f), m.frame_descriptors(f), frame.gravity_in_cam


def test_one_area_bundle_equals_the_single_model(tiny, tmp_path):
    m = lb.io.read_map(tiny.map)
    bundle = lb.load(write_bundle(tmp_path / "one", tiny.model, [("-inf", "inf")]))
    assert isinstance(bundle, lb.AreaBundle)
    assert bundle.num_areas == 1 and bundle.reach == 1.0 and bundle.loaded_ids == [] and not bundle.calibrated
    assert bundle.descriptor_bytes == -1  # nothing loaded yet
    localizer = lb.Localizer(lb.load(tiny.model))
    bundle_localizer = lb.BundleLocalizer(bundle)
    found = 0
    for f in m.query_frames:
        args = frame_args(m, f)
        single = localizer.localize(*args)
        r = bundle_localizer.localize(*args)
        assert r.scored == [0] and r.selected == 1 and r.errors == [] and not r.prior_used
        assert r.pose_found == single.pose_found
        if not single.pose_found:
            assert r.area == -1 and r.result is None and r.cam_from_world is None
            continue
        found += 1
        assert r.area == 0
        assert r.result.num_inliers == single.num_inliers == r.inliers[0]
        assert r.support[0] >= r.inliers[0]  # one match a keypoint: each inlier is a keypoint it explains
        assert r.rival_support == 0  # no other area
        assert not r.calibrated and r.confidence == -1.0 and r.localized == single.success
        assert r.result.success == single.success and r.result.confidence == single.confidence
        assert r.cam_from_world.rotation.tolist() == single.cam_from_world.rotation.tolist()
        assert r.cam_from_world.translation.tolist() == single.cam_from_world.translation.tolist()
        assert np.array_equal(r.result.correspondence_keypoint, single.correspondence_keypoint)
    assert found > 0
    assert bundle.loaded_ids == [0] and bundle.loads == 1 and bundle.descriptor_bytes == 64


def test_prior_selects_areas_and_a_damaged_area_fails_alone(tiny, tmp_path):
    m = lb.io.read_map(tiny.map)
#Area 0 : x < 1000(the tiny world); area 1 : x >= 1000, its file damaged.
    path = write_bundle(tmp_path / "two", tiny.model, [("-inf", "1000"), ("1000", "inf")])
    damaged = bytearray((tmp_path / "two" / "area-1.lbm").read_bytes())
    damaged[len(damaged) // 2] ^= 0x10
    (tmp_path / "two" / "area-1.lbm").write_bytes(bytes(damaged))
    bundle = lb.AreaBundle.open(path)
    assert [a["id"] for a in bundle.areas] == [0, 1]
    assert bundle.areas[1]["cell_lo"][0] == 1000.0 and bundle.areas[1]["cell_hi"][0] == np.inf
    assert bundle.select() == [0, 1]
    assert bundle.select((np.zeros(3), 5.0)) == [0]
    assert bundle.select(((2000.0, 0.0, 0.0), 5.0)) == [1]
    with pytest.raises(lb.Error, match=r"area 1 \(area-1.lbm\): CRC-32 mismatch"):
        bundle.model(1)
    f = m.query_frames[0]
    args = frame_args(m, f)
    centre = m.frames[f].cam_from_world.center()
    localizer = lb.BundleLocalizer(bundle)
#Without a prior both are selected : area 1 fails with one line naming it, area 0 localizes.
    r = localizer.localize(*args)
    assert r.selected == 2 and r.scored == [0] and len(r.errors) == 1
    assert "area 1 (area-1.lbm)" in r.errors[0] and "\n" not in r.errors[0]
#A prior at the frame selects area 0 only; one 2 km away selects only the damaged area.
    near = localizer.localize(*args, prior=(centre, 2.0))
    assert near.selected == 1 and near.scored == [0] and near.errors == [] and near.prior_used
    far = localizer.localize(*args, prior=(centre + np.array([2000.0, 0, 0]), 2.0))
    assert far.selected == 1 and far.scored == [] and far.area == -1 and len(far.errors) == 1
#Cache limits and release.
    bundle.set_cache_limits(max_areas=1)
    assert bundle.loaded_ids == [0]
    bundle.release_except([])
    assert bundle.loaded_ids == [] and bundle.loaded_bytes == 0


def test_winner_rules_and_tracking(tiny, tmp_path):
    m = lb.io.read_map(tiny.map)
    bundle = lb.load(write_bundle(tmp_path / "three", tiny.model, [("-inf", "0"), ("0", "inf")]))
    frames = m.query_frames
    by_support = lb.BundleLocalizer(bundle, search="all", winner="support")
    by_inliers = lb.BundleLocalizer(bundle, search="all", winner="inliers")
    for f in frames[:4]:
        a, b = by_support.localize(*frame_args(m, f)), by_inliers.localize(*frame_args(m, f))
#Two copies of one model : the same pose twice, ties go to the smaller id under both rules.
        assert a.scored == b.scored == [0, 1] and a.inliers == b.inliers and a.support == b.support
        assert a.inliers[0] == a.inliers[1] and a.support[0] == a.support[1]
        assert a.area == b.area == (0 if a.pose_found else -1)
    # Areas on two threads: the same results.
    threaded = lb.BundleLocalizer(bundle, search="all", area_threads=2)
    for f in frames[:4]:
        a, b = by_support.localize(*frame_args(m, f)), threaded.localize(*frame_args(m, f))
        assert (a.scored, a.inliers, a.support, a.area) == (b.scored, b.inliers, b.support, b.area)
        if a.pose_found:
            assert a.cam_from_world.translation.tolist() == b.cam_from_world.translation.tolist()
    # The winner's-view search with a prior (two areas: nothing to re-rank, so nearest first's result).
    nearest = lb.BundleLocalizer(bundle)
    for threads in (1, 2):
        view = lb.BundleLocalizer(bundle, search="winners_view", area_threads=threads)
        for f in frames[:2]:
            prior = (m.frames[f].cam_from_world.center(), 1.0)
            a, b = nearest.localize(*frame_args(m, f), prior=prior), view.localize(*frame_args(m, f), prior=prior)
            assert (a.scored, a.inliers, a.support, a.area) == (b.scored, b.inliers, b.support, b.area)
    tracker = lb.BundleLocalizer(bundle, tracking_radius=0.5)
    assert tracker.last_position is None
    first = tracker.track(*frame_args(m, frames[0]))
    assert not first.prior_used and first.selected == 2
    if first.pose_found:
        assert np.allclose(tracker.last_position, first.cam_from_world.center())
        second = tracker.track(*frame_args(m, frames[1]))
        assert second.prior_used or second.selected == 2
    # A known last pose: the same frame again lies inside the motion gate. Two areas are judged by
    # default, one on request; either way the pose is tracked (`localized` keeps its own meaning).
    if first.pose_found:
        for areas in (2, 1):
            gated = lb.BundleLocalizer(bundle, tracking_radius=50.0, tracking_areas=areas)  # selects both
            gated.last_pose = first.cam_from_world
            assert np.allclose(gated.last_position, first.cam_from_world.center())
            again = gated.track(*frame_args(m, frames[0]))
            assert again.prior_used and again.tracked and again.localized == again.result.success
            # An uncalibrated bundle has no walk calibration: the frame rule's verdict alone.
            assert again.walk is None and again.frame_localized == again.localized
            assert again.selected == 2 and len(again.scored) == areas
            assert np.allclose(gated.last_pose.translation, first.cam_from_world.translation)
        # What track() orders the areas by: two copies of one model see the same from the frame's
        # pose (with a reach beyond the world: the bundle above sees 1 m only).
        wide = lb.load(write_bundle(tmp_path / "wide", tiny.model, [("-inf", "0"), ("0", "inf")], reach=1000.0))
        camera = frame_args(m, frames[0])[0]
        seen = [wide.visible_landmarks(i, camera, first.cam_from_world) for i in range(2)]
        assert seen[0] == seen[1] > 0
        assert bundle.visible_landmarks(0, camera, first.cam_from_world) <= seen[0]
    # A relocalization prior restricts the first frame to the areas it selects (reach 1 m).
    relocalizing = lb.BundleLocalizer(bundle, tracking_radius=0.5)
    centre = m.frames[frames[0]].cam_from_world.center()
    by_fix = relocalizing.track(*frame_args(m, frames[0]), prior=(centre, 0.0))
    assert not by_fix.prior_used and by_fix.selected == len(bundle.select((centre, 0.0)))
    with pytest.raises(lb.Error, match="tracking_areas"):
        lb.BundleLocalizer(bundle, tracking_areas=0)
    tracker.reset_tracking()
    assert tracker.last_position is None and tracker.last_pose is None
    tracker.last_position = np.array([0.5, 0.0, 0.0])
    assert tracker.last_position.tolist() == [0.5, 0.0, 0.0] and tracker.last_pose is None
    assert tracker.bundle.num_areas == 2


def test_bad_input_raises_one_clear_error(tiny, tmp_path):
    m = lb.io.read_map(tiny.map)
    bundle = lb.load(write_bundle(tmp_path / "bad", tiny.model, [("-inf", "inf")]))
    localizer = lb.BundleLocalizer(bundle)
    camera, keypoints, descriptors, gravity = frame_args(m, m.query_frames[0])
    with pytest.raises(lb.Error, match="radius"):
        localizer.localize(camera, keypoints, descriptors, gravity, prior=(np.zeros(3), -1.0))
    with pytest.raises(lb.Error, match="not finite"):
        localizer.localize(camera, keypoints, descriptors, gravity, prior=((np.nan, 0.0, 0.0), 1.0))
    with pytest.raises(ValueError, match="prior"):
        localizer.localize(camera, keypoints, descriptors, gravity, prior=(np.zeros(3),))
    with pytest.raises(ValueError, match=r"descriptors: expected a uint8 array of shape \(\d+, 64\)"):
        localizer.localize(camera, keypoints, descriptors[:, :32], gravity)
    with pytest.raises(ValueError, match="winner 'most'"):
        lb.BundleLocalizer(bundle, winner="most")
    with pytest.raises(ValueError, match="search 'first'"):
        lb.BundleLocalizer(bundle, search="first")
    with pytest.raises(lb.Error, match="tracking_radius"):
        lb.BundleLocalizer(bundle, tracking_radius=-1.0)
    with pytest.raises(lb.Error, match="area_threads"):
        lb.BundleLocalizer(bundle, area_threads=0)
    (tmp_path / "index.txt").write_text("lmb-bundle 1\nreach x\n")
    with pytest.raises(lb.Error, match=r"index.txt line 2"):
        lb.load(tmp_path / "index.txt")
    (tmp_path / "other.txt").write_text("hello\n")
    with pytest.raises(lb.Error, match="neither a LandmarkBoost model"):
        lb.load(tmp_path / "other.txt")
