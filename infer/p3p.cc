#include "infer/p3p.h"

#include <opengv/absolute_pose/CentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/methods.hpp>

namespace lmb {

int p3p(const Eigen::Vector3d bearings[3], const Eigen::Vector3d points[3], std::vector<CameraPose>* solutions) {
  opengv::bearingVectors_t b(bearings, bearings + 3);
  opengv::points_t p(points, points + 3);
  opengv::absolute_pose::CentralAbsoluteAdapter adapter(b, p);
  const opengv::transformations_t world_from_cam = opengv::absolute_pose::p3p_kneip(adapter, 0, 1, 2);
  int added = 0;
  for (const opengv::transformation_t& T : world_from_cam) {
    if (!T.allFinite()) continue;
    // OpenGV: [R | c], R the camera's axes in the world and c its centre.
    CameraPose pose;
    pose.rotation = T.leftCols<3>().transpose();
    pose.translation = -(pose.rotation * T.col(3));
    solutions->push_back(pose);
    ++added;
  }
  return added;
}

}  // namespace lmb
