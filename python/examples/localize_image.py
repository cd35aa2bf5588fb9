#!/usr/bin/env python3
"""Localizes one image file with a model: keypoints and descriptors from the image (read and
detected as the mapper does, landmarkboost.cv), the camera from the map (or --camera), gravity from
the device.

    python3 python/examples/localize_image.py --model model.lbm --map map.h5 --image photo.jpg \\
        --gravity 0.12 0.65 0.75

--gravity is the direction of gravity (down) in the camera frame (x right, y down, z forward),
e.g. from the device's accelerometer, in the same convention as the map's gravity. Prints the
pose (cam_from_world), the camera centre in the map's frame and the inliers; exit code 1 when the
image is not localized.
"""
import argparse
import sys

import numpy as np

import landmarkboost as lb


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", required=True, help="model.lbm")
    p.add_argument("--image", required=True, help="the image file (any format OpenCV reads)")
    p.add_argument("--gravity", required=True, type=float, nargs=3, metavar=("GX", "GY", "GZ"),
                   help="gravity (down) in the camera frame")
    p.add_argument("--map", help="map.h5 whose first camera is the image's camera")
    p.add_argument("--camera", help="or the camera as 'MODEL WIDTH HEIGHT PARAMS...' (COLMAP)")
    p.add_argument("--top-k", type=int, default=1, help="matches kept per keypoint")
    args = p.parse_args()

    if args.camera:
        model, width, height, *params = args.camera.split()
        camera = lb.Camera(model, int(width), int(height), [float(v) for v in params])
    elif args.map:
        camera = lb.io.read_map(args.map).cameras[0]
    else:
        p.error("give --map or --camera")
    try:
        image = lb.cv.read_image(args.image)  # grey, decoded as the mapper decodes its images
    except lb.Error as e:
        sys.exit(str(e))
    if image.shape != (camera.height, camera.width):
        sys.exit(f"{args.image}: {image.shape[1]}x{image.shape[0]} pixels, the camera is "
                 f"{camera.width}x{camera.height}")
    features = lb.cv.detect_features(image)
    localizer = lb.Localizer(lb.load(args.model), lb.LocalizerOptions(top_k=args.top_k))
    r = localizer.localize(camera, features.keypoints, features.descriptors, args.gravity)
    print(f"{args.image}: {len(features.keypoints)} keypoints, {int(np.sum(np.diff(r.match_begin) > 0))} "
          f"with a match, {len(r.correspondence_match)} correspondences")
    if not r.success:
        print(f"{args.image}: not localized")
        sys.exit(1)
    pose = r.cam_from_world
    np.set_printoptions(precision=4, suppress=True)
    print(f"{args.image}: localized with {r.num_inliers} inliers in {r.timings_ms['total']:.1f} ms")
    print(f"cam_from_world rotation (w, x, y, z) {pose.rotation}, translation {pose.translation}")
    print(f"camera centre in the map {pose.center()}")


if __name__ == "__main__":
    main()
