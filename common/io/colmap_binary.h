// COLMAP sparse models in COLMAP's binary format (cameras.bin, images.bin, points3D.bin), as
// `colmap mapper` and `colmap model_converter --output_type BIN` write them. Everything is
// little-endian:
//   cameras.bin   uint64 count; per camera: uint32 camera_id, int32 model_id, uint64 width,
//                 uint64 height, double params[n(model)]
//   images.bin    uint64 count; per image: uint32 image_id, double qw qx qy qz tx ty tz (cam_from_world),
//                 uint32 camera_id, name bytes + NUL, uint64 num_points2D, then per point
//                 double x, double y, uint64 point3D_id (2^64-1 = none)
//   points3D.bin  uint64 count; per point: uint64 point3D_id, double x y z, uint8 r g b, double error,
//                 uint64 track_length, then per element uint32 image_id, uint32 point2D_idx
#pragma once

#include <filesystem>

#include "common/io/colmap_model.h"

namespace lmb {

// Reads cameras.bin and images.bin (and points3D.bin when present) from `sparse_dir`. Each file is
// read whole and parsed with bounds checks: every count is checked against the bytes left before
// anything is allocated. Throws lmb::Error with one line naming the file, the record (index and
// id), the byte offset and the reason: truncated file, count larger than the bytes left, unknown
// or unsupported camera model id, wrong sizes, non-finite values, non-unit quaternion, missing
// camera, duplicate id or name, name without its NUL terminator, trailing bytes.
ColmapModel read_colmap_binary(const std::filesystem::path& sparse_dir);

// Writes cameras.bin, images.bin and points3D.bin into `sparse_dir` (created if missing), byte
// for byte as COLMAP does. Throws lmb::Error when a file cannot be written or an id does not fit
// COLMAP's unsigned id types.
void write_colmap_binary(const ColmapModel& model, const std::filesystem::path& sparse_dir);

}  // namespace lmb
