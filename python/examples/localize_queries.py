#!/usr/bin/env python3
"""Localizes the query frames of a map with a model, in Python, and compares each pose with the
frame's ground truth (the map's pose):

    python3 python/examples/localize_queries.py --model out/default/model.lbm --map out/default/map.h5

The same poses as `lboost localize --model MODEL --map MAP` with the same options (bit for bit);
frames are localized on --threads Python threads (the GIL is released while localizing).
"""
import argparse
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import landmarkboost as lb
from landmarkboost import io


def rotation_error_deg(qa, qb):
    """Angle of the rotation between two unit quaternions (w, x, y, z), degrees."""
    wa, va, wb, vb = qa[0], qa[1:], qb[0], -qb[1:]  # qa * conjugate(qb)
    w = wa * wb - np.dot(va, vb)
    v = wa * vb + wb * va + np.cross(va, vb)
    return np.degrees(2 * np.arctan2(np.linalg.norm(v), abs(w)))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", required=True, help="model.lbm")
    p.add_argument("--map", required=True, help="map.h5 with query frames")
    p.add_argument("--top-k", type=int, default=1, help="matches kept per keypoint")
    p.add_argument("--inverted-file", action="store_true", help="score only the keypoint word's classes")
    p.add_argument("--threads", type=int, default=1)
    args = p.parse_args()

    m = io.read_map(args.map)
    localizer = lb.Localizer(lb.load(args.model),
                             lb.LocalizerOptions(top_k=args.top_k, use_inverted_file=args.inverted_file))

    def localize(f):
        frame = m.frames[f]
        return localizer.localize(m.cameras[frame.camera], m.frame_keypoints(f), m.frame_descriptors(f),
                                  frame.gravity_in_cam)

    start = time.perf_counter()
    with ThreadPoolExecutor(args.threads) as pool:
        results = list(pool.map(localize, m.query_frames))
    seconds = time.perf_counter() - start

    position_errors, rotation_errors = [], []
    for f, r in zip(m.query_frames, results):
        frame = m.frames[f]
        if r.success:
            # Ground truth: the map's pose of the frame. Errors: camera centre distance and the
            # angle of the relative rotation.
            dp = np.linalg.norm(r.cam_from_world.center() - frame.cam_from_world.center())
            dr = rotation_error_deg(r.cam_from_world.rotation, frame.cam_from_world.rotation)
            position_errors.append(dp)
            rotation_errors.append(dr)
            print(f"{frame.name}: localized, {r.num_inliers} inliers of {len(r.correspondence_match)}, "
                  f"error {dp:.3f} m {dr:.2f} deg")
        else:
            print(f"{frame.name}: not localized ({len(r.correspondence_match)} correspondences)")
    n = len(results)
    print(f"localized {len(position_errors)}/{n} query frames", end="")
    if position_errors:
        print(f", median error {np.median(position_errors):.3f} m {np.median(rotation_errors):.2f} deg", end="")
    print(f"; {1000 * seconds / max(n, 1):.1f} ms a frame on {args.threads} thread(s)")


if __name__ == "__main__":
    main()
