"""LandmarkBoost for Python: localize frames with a trained model, read maps and reports.

    import numpy as np
    import landmarkboost as lb

    model = lb.load("model.lbm")
    localizer = lb.Localizer(model, lb.LocalizerOptions(top_k=1))
    camera = lb.Camera("PINHOLE", 640, 480, [500.0, 500.0, 320.0, 240.0])
    result = localizer.localize(camera, keypoints, descriptors, gravity_in_cam)
    if result.success:
        print(result.cam_from_world.matrix())

    # A map split into areas (docs/areas.md): the areas a position prior selects compete.
    bundle = lb.load("bundle/bundle.txt")
    r = lb.BundleLocalizer(bundle).localize(camera, keypoints, descriptors, gravity_in_cam,
                                            prior=(gps_position, 10.0))
    if r.localized:
        print(r.area, r.confidence, r.cam_from_world.matrix())

keypoints: (n, 4) x, y, size, angle (COLMAP's pixel convention, OpenCV's KeyPoint.pt + 0.5);
descriptors: (n, model.descriptor_bytes) uint8; gravity_in_cam: gravity (down) in the camera
frame. The GIL is released while a frame is localized.

Submodules, loaded on first use so that an app that only localizes loads neither HDF5 nor OpenCV:
  landmarkboost.io   read_map("map.h5") (HDF5), read_report("report.json")
  landmarkboost.cv   detect_features(image): keypoints and descriptors of a numpy image, as the
                     mapper detects them (OpenCV)
"""
import importlib as _importlib
import os as _os
import sys as _sys

try:
    import numpy as _numpy  # noqa: F401  (the extension modules take and return numpy arrays)
except ImportError as _e:
    raise ImportError(f"landmarkboost needs numpy, which {_sys.executable} does not have (Debian: "
                      "apt-get install python3-numpy; the package is built for the interpreter "
                      "Python3_EXECUTABLE of the build's CMakeCache.txt, /usr/bin/python3 by default)") from _e

from ._core import (AreaBundle, BundleLocalizeResult, BundleLocalizer, Camera, Error, LocalizeResult,
                    Localizer, LocalizerOptions, Model, Rigid3d, WalkTracker, __version__)
from ._path import fspath as _fspath
from .report import Report, read_report

_MODEL_MAGIC = b"LMBMODEL"
_BUNDLE_MAGIC = b"lmb-bundle "


def load(path):
    """Loads a model file (model.lbm) for Localizer, or a bundle of area models (bundle.txt of
    `lboost bundle`) for BundleLocalizer. Raises landmarkboost.Error naming the file.

    A file is recognized by its first bytes (the model's magic, the bundle index's first line).
    path: str, bytes or os.PathLike (TypeError for anything else).
    """
    path = _fspath(path, "load: path")
    name = _os.fsdecode(path)
    try:
        with open(path, "rb") as f:
            magic = f.read(max(len(_MODEL_MAGIC), len(_BUNDLE_MAGIC)))
    except OSError as e:
        raise Error(f"{name}: cannot open ({e.strerror})") from None
    if magic.startswith(_MODEL_MAGIC):
        return Model.load(path)
    if magic.startswith(_BUNDLE_MAGIC):
        return AreaBundle.open(path)
    raise Error(f"{name}: neither a LandmarkBoost model (magic {_MODEL_MAGIC!r}) nor a bundle index "
                f"({_BUNDLE_MAGIC.decode()}...): starts with {magic!r}")


def __getattr__(name):
    if name in ("io", "cv"):
        return _importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'landmarkboost' has no attribute '{name}'")


__all__ = ["AreaBundle", "BundleLocalizeResult", "BundleLocalizer", "Camera", "Error", "LocalizeResult",
           "Localizer", "LocalizerOptions", "Model", "Report", "Rigid3d", "WalkTracker", "load",
           "read_report", "__version__"]
