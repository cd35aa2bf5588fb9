"""LandmarkBoost for Python: localize frames with a trained model, read maps and reports.

    import numpy as np
    import landmarkboost as lb

    model = lb.load("model.lbm")
    localizer = lb.Localizer(model, lb.LocalizerOptions(top_k=1))
    camera = lb.Camera("PINHOLE", 640, 480, [500.0, 500.0, 320.0, 240.0])
    result = localizer.localize(camera, keypoints, descriptors, gravity_in_cam)
    if result.success:
        print(result.cam_from_world.matrix())

keypoints: (n, 4) x, y, size, angle (COLMAP's pixel convention, OpenCV's KeyPoint.pt + 0.5);
descriptors: (n, model.descriptor_bytes) uint8; gravity_in_cam: gravity (down) in the camera
frame. The GIL is released while a frame is localized.

Submodules, loaded on first use so that an app that only localizes loads neither HDF5 nor OpenCV:
  landmarkboost.io   read_map("map.h5") (HDF5), read_report("report.json")
  landmarkboost.cv   detect_features(image): keypoints and descriptors of a numpy image, as the
                     mapper detects them (OpenCV)
"""
import importlib as _importlib
import sys as _sys

try:
    import numpy as _numpy  # noqa: F401  (the extension modules take and return numpy arrays)
except ImportError as _e:
    raise ImportError(f"landmarkboost needs numpy, which {_sys.executable} does not have (Debian: "
                      "apt-get install python3-numpy; the package is built for the interpreter "
                      "Python3_EXECUTABLE of the build's CMakeCache.txt, /usr/bin/python3 by default)") from _e

from ._core import (Camera, Error, LocalizeResult, Localizer, LocalizerOptions, Model, Rigid3d,
                    __version__)
from .report import Report, read_report

_MODEL_MAGIC = b"LMBMODEL"


def load(path):
    """Loads a model file (model.lbm) for Localizer. Raises landmarkboost.Error naming the file.

    The one entry point for what a Localizer takes: a file is recognized by its magic, so that
    other files (such as the per-area bundles of a large map) can be added here.
    """
    try:
        with open(path, "rb") as f:
            magic = f.read(len(_MODEL_MAGIC))
    except OSError as e:
        raise Error(f"{path}: cannot open ({e.strerror})") from None
    if magic == _MODEL_MAGIC:
        return Model.load(path)
    raise Error(f"{path}: not a LandmarkBoost model (magic {magic!r}, expected {_MODEL_MAGIC!r})")


def __getattr__(name):
    if name in ("io", "cv"):
        return _importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'landmarkboost' has no attribute '{name}'")


__all__ = ["Camera", "Error", "LocalizeResult", "Localizer", "LocalizerOptions", "Model", "Report",
           "Rigid3d", "load", "read_report", "__version__"]
