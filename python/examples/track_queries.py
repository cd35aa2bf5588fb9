#!/usr/bin/env python3
"""Tracks the query frames of a map through a bundle of area models, in capture order, the way an
app tracks a camera, and compares each pose with the frame's ground truth (the map's pose):

    python3 python/examples/track_queries.py --bundle bundle/bundle.txt --map map.h5 --radius 1

The first frame, and a frame the tracker loses, are relocalized in every area (or, with --gps-noise
M, in the areas a position prior of the true centre moved M metres selects, as a GPS fix would).
The same poses as `lboost localize --bundle BUNDLE --map MAP --track RADIUS` with the same options.
"""
import argparse
import time

import numpy as np

import landmarkboost as lb
from landmarkboost import io


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--bundle", required=True, help="bundle.txt of `lboost bundle`")
    p.add_argument("--map", required=True, help="map.h5 with query frames")
    p.add_argument("--radius", type=float, default=1.0, help="how far the camera moves between two frames, metres")
    p.add_argument("--tracking-areas", type=int, default=2, help="areas scored before the motion gate judges")
    p.add_argument("--gps-noise", type=float, default=None, help="relocalize with a prior this far off, metres")
    p.add_argument("--inverted-file", action="store_true", help="score only the keypoint word's classes")
    args = p.parse_args()

    m = io.read_map(args.map)
    bundle = lb.load(args.bundle)
    tracker = lb.BundleLocalizer(bundle, lb.LocalizerOptions(use_inverted_file=args.inverted_file),
                                 tracking_radius=args.radius, tracking_areas=args.tracking_areas)
    frames = sorted(m.query_frames, key=lambda f: m.frames[f].name)  # capture order
    rng = np.random.default_rng(1)
    tracked = right = reported = reported_right = 0
    times = []
    for f in frames:
        frame = m.frames[f]
        prior = None
        if args.gps_noise is not None:  # a GPS-like fix: the true centre moved gps_noise metres
            direction = rng.normal(size=3)
            prior = (frame.cam_from_world.center() + args.gps_noise * direction / np.linalg.norm(direction),
                     args.gps_noise)
        start = time.perf_counter()
        r = tracker.track(m.cameras[frame.camera], m.frame_keypoints(f), m.frame_descriptors(f),
                          frame.gravity_in_cam, prior=prior)
        times.append(1000 * (time.perf_counter() - start))
        how = "tracked" if r.tracked else ("relocalized" if not r.prior_used else "not tracked")
        if r.pose_found:
            error = np.linalg.norm(r.cam_from_world.center() - frame.cam_from_world.center())
            right += error <= 0.2
            # `localized` is the answer to act on: with a walk-calibrated bundle, the walk's verdict.
            reported += r.localized
            reported_right += r.localized and error <= 0.2
            verdict = "localized" if r.localized else "not localized"
            print(f"{frame.name}: {how}, area {r.area} of {len(r.scored)} scored, error {error:.3f} m, {verdict}, "
                  f"{times[-1]:.1f} ms")
        else:
            print(f"{frame.name}: {how}, no pose, {times[-1]:.1f} ms")
        tracked += r.tracked
    n = len(frames)
    print(f"tracked {tracked}/{n} query frames, {right} within 0.2 m, {reported} localized ({reported_right} within "
          f"0.2 m); "
          f"{np.median(times) if times else 0:.1f} ms a frame (median), {np.mean(times) if times else 0:.1f} (mean)")


if __name__ == "__main__":
    main()
