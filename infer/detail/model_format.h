// Internal (not installed): the model file's magic, versions and payload coding (the format is
// described in infer/model.h). Model::load, from_bytes, save and to_bytes are the public way in.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "infer/model.h"

namespace lmb {

constexpr const char* kModelMagic = "LMBMODEL";
// Version 2 appends the descriptor-distance fusion (DescriptorFusion); version 3 an optional
// fusion and the pose calibration (PoseCalibration); version 4 adds the walk calibration
// (WalkCalibration); version 5 the walk calibration's agreement and whether its walk rule adds
// poses. A model is written in the oldest version that holds it: a walk calibration without
// agreement that adds poses as version 4, without a walk calibration as version 3, without a pose
// calibration as version 1 or 2. All five are read; a model of version 1 or 2 is uncalibrated
// (Model::calibrated() false).
constexpr uint32_t kModelVersionWithAgreement = 5;
constexpr uint32_t kModelVersionWithWalk = 4;
constexpr uint32_t kModelVersion = 3;
constexpr uint32_t kModelVersionWithFusion = 2;
constexpr uint32_t kModelVersionWithoutFusion = 1;

// The payload (cereal portable binary, see infer/model.h) and its inverse. parse throws
// lmb::Error naming `what` for truncated or corrupt bytes, a count larger than the bytes left,
// or contents that fail ModelData::check. The payload's version is model_file_version(data):
// kModelVersionWithAgreement or kModelVersionWithWalk with a walk calibration, kModelVersion with a calibration, else
// kModelVersionWithFusion with a fusion, else kModelVersionWithoutFusion; parse reads each.
std::string serialize_model_data(const ModelData& data);
ModelData parse_model_data(const std::string& payload, const std::string& what, uint32_t version = kModelVersion);
uint32_t model_file_version(const ModelData& data);

namespace detail {
// LEB128 varint gap coding of an ascending id list (first id, then differences), and its
// bounds-checked inverse: decode throws lmb::Error naming `what` when the bytes end early, hold
// extra bytes, a gap is zero after the first id, or an id exceeds max_id.
std::string encode_ascending_ids(const std::vector<int32_t>& ids);
std::vector<int32_t> decode_ascending_ids(const std::string& bytes, uint32_t count, int32_t max_id,
                                          const std::string& what);
}  // namespace detail

}  // namespace lmb
