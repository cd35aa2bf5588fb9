// `lboost world`: renders a World's sessions (WorldOptions::map_sessions map sessions, then
// query_sessions query sessions; train/world/trajectory.h) and writes them as a collection:
//
//   DIR/sparse/{cameras,images,points3D}.txt   COLMAP text model (one OPENCV camera, id 1; images
//                                               "SESSION/NNNNNN.png" session after session, ids
//                                               from 1; no 2D points, no 3D points)
//   DIR/sessions.txt                            the sessions, "NAME KIND" (common/io/session_file.h):
//                                               map, map-2, ... (map), query, query-2, ... (query),
//                                               outside (outside; WorldOptions::outside_frames)
//   DIR/images/SESSION/NNNNNN.png              8-bit grayscale renders
//   DIR/depth/SESSION/NNNNNN.png               16-bit z-depth of each pixel centre in mm (0 = none)
//   DIR/world.json                             preset, seed, up axis, counts, camera, geometry,
//                                               lighting and trajectory of each session
//
// Everything is written into a temporary sibling folder that is renamed to DIR at the end, so an
// interrupted run leaves no valid-looking output. Byte-identical for the same options.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "train/world/world_model.h"

namespace lmb {

struct WorldWriteStats {
  int map_frames = 0;           // over all map sessions
  int query_frames = 0;         // over all query sessions
  int outside_frames = 0;       // the outside session's
  double build_seconds = 0.0;   // textures and layout
  double render_seconds = 0.0;  // rendering and PNG writing
  WorldSummary summary;
};

// Renders and writes the collection for `options` into `out_dir`. An existing `out_dir` is
// replaced only when it is empty or holds a previous world (has world.json). Throws lmb::Error for
// invalid options, an unusable output folder (not creatable, not writable, another folder's
// contents), or a failed image write. `progress` (optional) is called after each frame with
// (frames done, frames total).
WorldWriteStats write_world(const WorldOptions& options, const std::filesystem::path& out_dir,
                            const std::function<void(int, int)>& progress = {});

}  // namespace lmb
