#include "train/boost/stump_learner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "common/error.h"
#include "common/random.h"
#include "train/boost/screening_gain.h"

namespace lmb {

namespace {

constexpr uint64_t kDrawTag = 0x4452415744494D53ull;  // dims of F_m

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// The learner's inputs, checked before any part reads them.
const FeatureMatrix& checked(const FeatureMatrix& features, const TrainingSet& set, const BoostOptions& options) {
  options.check(features.num_dims);
  set.check();
  LMB_CHECK(features.num_samples == set.num_samples(),
            "features: " << features.num_samples << " rows for " << set.num_samples() << " training samples");
  LMB_CHECK(static_cast<int64_t>(features.data.size()) ==
                static_cast<int64_t>(features.num_stored_columns()) * features.num_samples,
            "features: data holds " << features.data.size() << " bytes, expected " << features.num_stored_columns()
                                    << " columns x " << features.num_samples);
  LMB_CHECK(features.num_samples < std::numeric_limits<int32_t>::max(),
            "features: " << features.num_samples << " samples; at most 2^31 - 2 are supported");
  return features;
}

}  // namespace

std::vector<int32_t> draw_round_dims(uint64_t seed, int32_t round, int32_t num_dims, int32_t k) {
  LMB_CHECK(k >= 0 && k <= num_dims, "draw_round_dims: " << k << " of " << num_dims << " dims");
  std::vector<std::pair<uint64_t, int32_t>> keyed(static_cast<size_t>(num_dims));
  for (int32_t d = 0; d < num_dims; ++d) {
    keyed[d] = {counter_hash(seed, kDrawTag, static_cast<uint64_t>(round), static_cast<uint64_t>(d)), d};
  }
  std::nth_element(keyed.begin(), keyed.begin() + k, keyed.end());
  std::vector<int32_t> dims;
  dims.reserve(static_cast<size_t>(k));
  for (int32_t i = 0; i < k; ++i) dims.push_back(keyed[i].second);
  std::sort(dims.begin(), dims.end());
  return dims;
}

SerialStumpLearner::SerialStumpLearner(const FeatureMatrix& features, const TrainingSet& set,
                                       const BoostOptions& options, Collectives& comm)
    : features_(checked(features, set, options)),
      set_(set),
      options_(options),
      comm_(comm),
      C1_(set.num_classes_with_background()),
      columns_(features, options_.screening),
      entries_(features.num_samples, C1_),
      search_(columns_, entries_, options_),
      rows_(set, comm),
      miner_(set, options_) {
  model_.num_dims = features.num_dims;
  model_.num_classes = set.num_classes;
  model_.class_landmark = set.class_landmark;
  model_.bias.assign(static_cast<size_t>(C1_), 0.0);
}

void SerialStumpLearner::initialize() {
  if (initialized_) return;
  miner_.bootstrap(&entries_);
  rows_.select(options_);
  initialized_ = true;
}

std::vector<int32_t> SerialStumpLearner::choose_dims(int32_t /*round*/, const std::vector<int32_t>& round_dims) {
  for (int32_t d : round_dims) {
    LMB_CHECK(columns_.stored(d), "boost: dim " << d << " of F_m is not stored in this feature matrix");
  }
  return round_dims;
}

std::vector<ScreenedCandidate> SerialStumpLearner::select_for_refinement(std::vector<ScreenedCandidate> local) {
  return best_candidates(std::move(local), options_.screening.refine_top);
}

StumpRecord SerialStumpLearner::reduce_best(StumpRecord local, std::vector<uint8_t>* above) {
  if (local.valid()) {
    columns_.above(local.dim, local.theta, above);
  } else {
    above->assign(static_cast<size_t>(features_.num_samples), 0);
  }
  return local;
}

std::vector<ScreenedCandidate> SerialStumpLearner::screen(std::vector<int32_t> dims) {
  initialize();
  entries_.quantize(rounds_done());
  return search_.screen(std::move(dims));
}

StumpRecord SerialStumpLearner::search(const std::vector<int32_t>& dims) {
  initialize();
  entries_.quantize(rounds_done());
  double seconds = 0.0;
  return search_.run(
      dims, [this](std::vector<ScreenedCandidate> c) { return select_for_refinement(std::move(c)); }, &seconds);
}

RoundStats SerialStumpLearner::run_round() {
  initialize();
  const auto t0 = Clock::now();
  RoundStats stats;
  stats.round = rounds_done();
  LMB_CHECK(stats.round < options_.num_rounds, "boost: all " << options_.num_rounds << " rounds are done");
  if (options_.mining.interval > 0 && stats.round > 0 && stats.round % options_.mining.interval == 0) {
    const auto tm = Clock::now();
    stats.mined = miner_.mine(rows_, comm_, &entries_);
    stats.seconds_eval += seconds_since(tm);
  }
  entries_.quantize(stats.round);
  stats.cost_before = entries_.exp_loss();
  columns_.drop_lent();

  const std::vector<int32_t> round_dims = draw_round_dims(
      options_.seed, stats.round, options_.candidate_dims > 0 ? options_.candidate_dims : features_.num_dims,
      options_.dims_per_round);
  const std::vector<int32_t> dims = choose_dims(stats.round, round_dims);
  const auto ts = Clock::now();
  double pass_seconds = 0.0;
  StumpRecord local = search_.run(
      dims, [this](std::vector<ScreenedCandidate> c) { return select_for_refinement(std::move(c)); }, &pass_seconds);
  stats.seconds_histogram += pass_seconds;
  stats.seconds_search += seconds_since(ts) - pass_seconds;
  std::vector<uint8_t> above;
  const StumpRecord best = reduce_best(std::move(local), &above);

  const auto tu = Clock::now();
  apply(best, above, &stats);
  stats.seconds_update = seconds_since(tu);
  // The gain is in this round's fixed-point units.
  stats.gain = best.valid() ? std::ldexp(best.gain, entries_.weight_exponent() - entries_.quant_shift()) : 0.0;
  stats.dim = best.dim;
  stats.theta = best.theta;
  stats.sharing_size = static_cast<int32_t>(best.classes.size());
  stats.num_entries = entries_.size();
  if (options_.validation.interval > 0 &&
      ((stats.round + 1) % options_.validation.interval == 0 || stats.round + 1 == options_.num_rounds)) {
    const auto tv = Clock::now();
    rows_.validation_precision(&stats.validation_p1, &stats.validation_p1_landmarks);
    last_validation_ = stats.validation_p1;
    stats.seconds_eval += seconds_since(tv);
  }
  stats.seconds = seconds_since(t0);
  return stats;
}

void SerialStumpLearner::apply(const StumpRecord& best, const std::vector<uint8_t>& above, RoundStats* stats) {
  // Fit: k_c for every class (its own constant), (alpha, beta) for the sharing set, all shrunk.
  const double nu = options_.learning_rate;
  std::vector<double> k(static_cast<size_t>(C1_));
  for (int32_t c = 0; c < C1_; ++c) {
    const int64_t w = entries_.class_w()[c];
    k[c] = w > 0 ? static_cast<double>(entries_.class_y()[c]) / static_cast<double>(w) : 0.0;
    k[c] *= nu;
  }
  std::vector<uint8_t> in_set(static_cast<size_t>(C1_), 0);
  double alpha = 0.0, beta = 0.0;
  SharedStump stump;
  if (best.valid()) {
    for (int32_t c : best.classes) in_set[c] = 1;
    screening::fit_point(static_cast<double>(best.wp), static_cast<double>(best.yp), static_cast<double>(best.wm),
                         static_cast<double>(best.ym), &alpha, &beta);
    alpha *= nu;
    beta *= nu;
    stump.dim = best.dim;
    stump.theta = static_cast<uint8_t>(best.theta);
    stump.a = alpha - beta;
    stump.b = beta;
    stump.classes = best.classes;
  }
  const EntryStore::UpdateSums sums = entries_.update(above, in_set, alpha, beta, k);
  stats->squared_error = sums.squared_error;
  stats->cost = sums.cost;
  LMB_CHECK(std::isfinite(stats->cost) && std::isfinite(stats->squared_error),
            "boost: the training cost became non-finite at round " << stats->round);
  if (best.valid()) {
    const size_t n = best.classes.size();
    std::vector<float> d_above(n), d_below(n);
    for (size_t j = 0; j < n; ++j) {
      d_above[j] = static_cast<float>(alpha - k[best.classes[j]]);
      d_below[j] = static_cast<float>(beta - k[best.classes[j]]);
    }
    rows_.add_stump(best.classes, std::move(d_above), std::move(d_below), above);
  }
  rows_.add_constants(k);
  for (int32_t c = 0; c < C1_; ++c) {
    if (!in_set[c]) model_.bias[c] += k[c];
  }
  model_.stumps.push_back(std::move(stump));
}

void SerialStumpLearner::train(const std::function<void(const RoundStats&)>& on_round) {
  while (rounds_done() < options_.num_rounds) {
    const RoundStats stats = run_round();
    if (on_round) on_round(stats);
  }
}

double SerialStumpLearner::validation_precision(bool exclude_background) {
  double all = -1.0, landmarks = -1.0;
  rows_.validation_precision(&all, &landmarks);
  return exclude_background ? landmarks : all;
}

LearnerState SerialStumpLearner::save_state() {
  initialize();
  LearnerState st;
  st.model = model_;
  entries_.save(&st);
  rows_.save(&st);
  miner_.save(&st);
  st.last_validation = last_validation_;
  return st;
}

void SerialStumpLearner::restore_state(const LearnerState& st) {
  entries_.check(st);
  LMB_CHECK(static_cast<int64_t>(st.model.bias.size()) == C1_,
            "learner state: " << st.model.bias.size() << " biases for " << C1_ << " classes");
  LMB_CHECK(st.model.num_dims == features_.num_dims && st.model.num_classes == set_.num_classes,
            "learner state: a model of " << st.model.num_classes << " classes x " << st.model.num_dims << " dims for "
                                         << set_.num_classes << " x " << features_.num_dims);
  LMB_CHECK(static_cast<int32_t>(st.model.stumps.size()) <= options_.num_rounds,
            "learner state: " << st.model.stumps.size() << " rounds done, more than boost.num_rounds "
                              << options_.num_rounds);
  st.model.check();
  miner_.check(st);
  rows_.check(st);
  entries_.restore(st);
  rows_.restore(st);
  miner_.restore(st);
  model_ = st.model;
  last_validation_ = st.last_validation;
  initialized_ = true;
}

}  // namespace lmb
