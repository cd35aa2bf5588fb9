"""landmarkboost.cv: the OpenCV front-end on numpy images, against the map's own detections."""
import numpy as np
import pytest
from PIL import Image

import landmarkboost as lb
from landmarkboost import cv


def test_detect_features_equals_the_mappers_detections(tiny):
    m = lb.io.read_map(tiny.map)
    f = m.query_frames[0]
    frame = m.frames[f]
    image = np.asarray(Image.open(tiny.collection / "images" / frame.name))
    assert image.dtype == np.uint8 and image.ndim == 2  # the rendered world's grey PNG
    features = cv.detect_features(image)
    assert np.array_equal(features.keypoints, m.frame_keypoints(f))
    assert np.array_equal(features.descriptors, m.frame_descriptors(f))
    assert np.all(np.diff(features.responses) <= 0)
    assert features.keypoints.flags.writeable and features.keypoints.base is not None  # no copy out
    # A view with a row stride (the left half of a wider array) and a column-strided view (every
    # other column; copied) give the same result.
    wide = np.zeros((image.shape[0], image.shape[1] * 2), np.uint8)
    wide[:, :image.shape[1]] = image
    assert np.array_equal(cv.detect_features(wide[:, :image.shape[1]]).descriptors, features.descriptors)
    wide[:, ::2] = image
    assert np.array_equal(cv.detect_features(wide[:, ::2]).descriptors, features.descriptors)
    # ... and localizes like the map's keypoints.
    localizer = lb.Localizer(lb.load(tiny.model))
    r = localizer.localize(m.cameras[frame.camera], features.keypoints, features.descriptors, frame.gravity_in_cam)
    r_map = localizer.localize(m.cameras[frame.camera], m.frame_keypoints(f), m.frame_descriptors(f),
                               frame.gravity_in_cam)
    assert r.cam_from_world.rotation.tolist() == r_map.cam_from_world.rotation.tolist()


def test_colour_orders_options_and_errors():
    rng = np.random.default_rng(3)
    rgb = (rng.random((120, 160, 3)) * 255).astype(np.uint8)
    rgb[40:80, 50:110] = [250, 20, 90]
    a = cv.detect_features(rgb)
    b = cv.detect_features(np.ascontiguousarray(rgb[..., ::-1]), channels="BGR")
    c = cv.detect_features(np.dstack([rgb, np.full(rgb.shape[:2], 255, np.uint8)]), channels="RGB")
    assert len(a.keypoints) > 0
    for other in (b, c):
        assert np.array_equal(a.keypoints, other.keypoints) and np.array_equal(a.descriptors, other.descriptors)
    orb = cv.detect_features(rgb, detector="ORB", max_keypoints=50)
    assert orb.descriptors.shape[1] == 32 and 0 < len(orb.keypoints) <= 50
    with pytest.raises(ValueError, match=r"image: expected a uint8 array .* got a float64 array of shape \(4, 4\)"):
        cv.detect_features(np.zeros((4, 4)))
    with pytest.raises(ValueError, match="channels: 'HSV'"):
        cv.detect_features(rgb, channels="HSV")
    with pytest.raises(lb.Error, match="max_keypoints"):
        cv.detect_features(rgb, max_keypoints=0)
    with pytest.raises(lb.Error, match="unknown detector 'SIFT'"):
        cv.detect_features(rgb, detector="SIFT")


def test_images_smaller_than_the_detector_takes_raise_landmarkboost_error():
    for image in (np.zeros((4, 5), np.uint8), np.zeros((4, 5, 3), np.uint8), np.zeros((1, 1), np.uint8)):
        h, w = image.shape[:2]
        with pytest.raises(lb.Error, match=rf"^detect_features: image is {w}x{h} pixels, smaller than the 6x6 that "
                                           r"BRISK with 3 octaves takes$"):
            cv.detect_features(image)
    with pytest.raises(lb.Error, match="image is 1x3 pixels, smaller than the 2x2 that ORB takes"):
        cv.detect_features(np.zeros((3, 1), np.uint8), detector="ORB")
    assert len(cv.detect_features(np.zeros((6, 6), np.uint8)).keypoints) == 0


def test_read_image_decodes_as_the_mapper(tiny, tmp_path):
    m = lb.io.read_map(tiny.map)
    f = m.query_frames[0]
    path = tiny.collection / "images" / m.frames[f].name
    image = cv.read_image(path)
    assert image.dtype == np.uint8 and image.shape == (m.cameras[0].height, m.cameras[0].width)
    assert np.array_equal(image, np.asarray(Image.open(path).convert("L")))  # PNG: one decoding
    assert np.array_equal(cv.detect_features(image).descriptors, m.frame_descriptors(f))
    # A colour JPEG: grey as OpenCV's imread(..., IMREAD_GRAYSCALE), i.e. its decoder and its grey
    # weights; close to PIL's (whose JPEG decoding differs by a few grey levels at edges).
    rgb = np.dstack([image, image[::-1], 255 - image])
    Image.fromarray(rgb).save(tmp_path / "c.jpg", quality=90)
    grey = cv.read_image(tmp_path / "c.jpg")
    pil = np.asarray(Image.open(tmp_path / "c.jpg").convert("L")).astype(int)
    assert grey.shape == pil.shape and np.abs(grey.astype(int) - pil).max() <= 12
    assert np.abs(grey.astype(int) - pil).mean() < 1
    with pytest.raises(lb.Error, match=f"{tmp_path / 'none.png'}: cannot read the image: no such file"):
        cv.read_image(tmp_path / "none.png")
    (tmp_path / "text.png").write_text("not an image")
    with pytest.raises(lb.Error, match="text.png: cannot read the image: not a format OpenCV decodes"):
        cv.read_image(tmp_path / "text.png")
