// Which gravity `lboost map` gives a collection's frames, and why. The sources, in order:
//   --gravity FILE     the file (per image; exclusive with --up);
//   --gravity none     -up of --up (COLLECTION/gravity.txt, if any, is ignored);
//   COLLECTION/gravity.txt, when present and --gravity is not given: the file; when --up is also
//                      given, the file and the axis are compared image by image: if they disagree
//                      (median angle above kMaxGravityDisagreementDeg) that is an error, otherwise
//                      --up is used and the agreement is reported;
//   otherwise          -up of --up (default +z).
// The choice comes with a one-line description for the user (what is used, from where).
#pragma once

#include <filesystem>
#include <string>

#include <Eigen/Core>

namespace lmb {

// Median angle between a gravity file and an explicit --up above which `lboost map` refuses to
// choose between them.
constexpr double kMaxGravityDisagreementDeg = 30.0;

struct MapGravityRequest {
  std::filesystem::path collection;  // the collection folder (sparse/, images/, gravity.txt)
  std::string gravity;               // --gravity: "" (not given), "none", or a file path
  std::string up = "+z";             // --up
  bool up_given = false;             // --up was on the command line
};

struct MapGravityChoice {
  std::filesystem::path gravity_file;  // the file to use; empty: gravity is -up
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  // What is used and why, e.g. "per image from work/c/gravity.txt (found in the collection; ...)".
  std::string description;
  // When both an explicit --up and COLLECTION/gravity.txt exist: the angles between them over the
  // images (degrees); images = 0 otherwise.
  int images_compared = 0;
  double median_angle_deg = 0.0;
  double max_angle_deg = 0.0;
};

// Resolves the request. Throws lmb::Error (one line, naming the flags or file) for --gravity FILE
// together with --up, a missing file, an unparsable --up, or a gravity.txt that disagrees with an
// explicit --up; reading COLLECTION/gravity.txt for the comparison reports that file's errors.
MapGravityChoice choose_map_gravity(const MapGravityRequest& request);

}  // namespace lmb
