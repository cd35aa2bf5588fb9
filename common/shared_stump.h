// One shared decision stump of the JointBoost classifier: what the trainer learns
// (train/boost/boost_model.h) and what the inference model stores (infer/model.h).
//
//   h(v, c) = c in classes ? (v[dim] > theta ? a + b : b) : 0
//
// The trainer's stumps also fit a constant k_c for every class outside the sharing set; both
// models fold those into the class biases, so a stump holds only what it adds to its classes.
#pragma once

#include <cstdint>
#include <vector>

namespace lmb {

struct SharedStump {
  int32_t dim = -1;              // feature dimension (common/context_embedding.h layout); -1 = none
                                 // (a constant-only round of the trainer, with an empty set)
  uint8_t theta = 0;             // fires when the bin is > theta; theta in 0..254
  double a = 0.0;                // step height
  double b = 0.0;                // value at or below the threshold
  std::vector<int32_t> classes;  // sharing set S, ascending; classes 0..C (C = background)

  bool operator==(const SharedStump& o) const {
    return dim == o.dim && theta == o.theta && a == o.a && b == o.b && classes == o.classes;
  }
  bool operator!=(const SharedStump& o) const { return !(*this == o); }
  // cereal (the trainer's model.bin and checkpoints; the inference model has its own format).
  template <class Archive>
  void serialize(Archive& ar) {
    ar(dim, theta, a, b, classes);
  }
};

}  // namespace lmb
