"""The OpenCV front-end: keypoints and binary descriptors of a numpy image, detected exactly as
`lboost map` detects map images (same code, same defaults).

    features = landmarkboost.cv.detect_features(image)          # uint8 (h, w) or (h, w, 3|4)
    result = localizer.localize(camera, features.keypoints, features.descriptors, gravity)

Colour images are RGB(A) unless channels="BGR" (OpenCV's order, e.g. from cv2.imread). The mapper
reads image files as grey with OpenCV (cv::imread(..., IMREAD_GRAYSCALE)); read_image(path) does the
same, so its features are the mapper's exactly (other decoders, e.g. PIL's for JPEG, give slightly
different pixels, hence a few different keypoints).

    features = landmarkboost.cv.detect_features(landmarkboost.cv.read_image("photo.jpg"))
"""
import os
from typing import NamedTuple

import numpy as np

from . import _cv
from ._path import fspath


class Features(NamedTuple):
    keypoints: np.ndarray    # (n, 4) float32: x, y, size, angle (COLMAP's pixel convention)
    descriptors: np.ndarray  # (n, bytes) uint8
    responses: np.ndarray    # (n,) float32, decreasing


def detect_features(image, channels="RGB", **options):
    """Detects keypoints and computes their descriptors.

    options (defaults: the mapper's): detector ("BRISK", 64-byte descriptors, or "ORB", 32 bytes),
    max_keypoints (the strongest, 1500), brisk_threshold (30), brisk_octaves (3). Deterministic
    for a given image. Raises ValueError for an image that is not 8-bit with 1, 3 or 4 channels and
    landmarkboost.Error for invalid detector options.
    """
    return Features(*_cv.detect_features(np.asarray(image), channels, **options))


def read_image(path):
    """The image file as an 8-bit grey (h, w) numpy array, decoded as `lboost map` decodes it
    (OpenCV, grey). path: str, bytes or os.PathLike (TypeError for anything else). Raises
    landmarkboost.Error naming the file when it cannot be read."""
    return _cv.read_image(os.fsdecode(fspath(path, "read_image: path")))


__all__ = ["Features", "detect_features", "read_image"]
