"""LandmarkBoost files: map.h5 (read_map, through the C++ reader, HDF5) and report.json
(read_report, plain Python).

    m = landmarkboost.io.read_map("map.h5")
    for f in m.query_frames:
        frame = m.frames[f]
        keypoints, descriptors = m.frame_keypoints(f), m.frame_descriptors(f)
        camera, gravity = m.cameras[frame.camera], frame.gravity_in_cam
"""
from ._io import Frame, Map, read_map
from .report import Report, read_report

__all__ = ["Frame", "Map", "Report", "read_map", "read_report"]
