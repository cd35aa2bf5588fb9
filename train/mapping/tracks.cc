#include "train/mapping/tracks.h"

#include <algorithm>
#include <tuple>
#include <unordered_map>

#include "common/error.h"

namespace lmb {

namespace {

class ConflictFreeUnionFind {
 public:
  explicit ConflictFreeUnionFind(const std::vector<frame_t>& keypoint_frame) : keypoint_frame_(keypoint_frame) {}

  int64_t find(int64_t x) {
    auto it = parent_.find(x);
    if (it == parent_.end()) return x;
    int64_t root = x;
    while (true) {
      auto p = parent_.find(root);
      if (p == parent_.end() || p->second == root) break;
      root = p->second;
    }
    // Path compression.
    while (x != root) {
      auto p = parent_.find(x);
      const int64_t next = p->second;
      p->second = root;
      x = next;
    }
    return root;
  }

  const std::vector<frame_t>& frames_of(int64_t root) {
    auto it = frames_.find(root);
    if (it == frames_.end()) it = frames_.emplace(root, std::vector<frame_t>{keypoint_frame_[root]}).first;
    return it->second;
  }

  // Merges the sets of a and b unless they share a frame. Returns whether they are joined.
  bool unite(int64_t a, int64_t b) {
    int64_t ra = find(a), rb = find(b);
    if (ra == rb) return true;
    const std::vector<frame_t>& fa = frames_of(ra);
    const std::vector<frame_t>& fb = frames_of(rb);
    size_t i = 0, j = 0;
    while (i < fa.size() && j < fb.size()) {
      if (fa[i] == fb[j]) return false;
      if (fa[i] < fb[j]) {
        ++i;
      } else {
        ++j;
      }
    }
    std::vector<frame_t> merged;
    merged.reserve(fa.size() + fb.size());
    std::merge(fa.begin(), fa.end(), fb.begin(), fb.end(), std::back_inserter(merged));
    if (fa.size() < fb.size()) std::swap(ra, rb);  // attach the smaller set below the larger
    parent_[rb] = ra;
    parent_.emplace(ra, ra);
    frames_[ra] = std::move(merged);
    frames_.erase(rb);
    return true;
  }

 private:
  const std::vector<frame_t>& keypoint_frame_;
  std::unordered_map<int64_t, int64_t> parent_;
  std::unordered_map<int64_t, std::vector<frame_t>> frames_;
};

}  // namespace

std::vector<std::vector<int64_t>> build_tracks(const std::vector<frame_t>& keypoint_frame,
                                               std::vector<KeypointMatch> matches) {
  const int64_t n = static_cast<int64_t>(keypoint_frame.size());
  for (KeypointMatch& m : matches) {
    LMB_CHECK(m.a >= 0 && m.a < n && m.b >= 0 && m.b < n, "build_tracks: match index outside 0.." << n - 1);
    if (m.a > m.b) std::swap(m.a, m.b);
  }
  std::sort(matches.begin(), matches.end(), [](const KeypointMatch& x, const KeypointMatch& y) {
    return std::tie(x.distance, x.a, x.b) < std::tie(y.distance, y.a, y.b);
  });
  ConflictFreeUnionFind uf(keypoint_frame);
  std::vector<int64_t> touched;
  for (const KeypointMatch& m : matches) {
    if (keypoint_frame[m.a] == keypoint_frame[m.b]) continue;
    if (uf.unite(m.a, m.b)) {
      touched.push_back(m.a);
      touched.push_back(m.b);
    }
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  std::unordered_map<int64_t, size_t> track_of_root;
  std::vector<std::vector<int64_t>> tracks;
  for (int64_t k : touched) {  // increasing k: tracks come out ordered by first keypoint, sorted inside
    const int64_t root = uf.find(k);
    auto [it, inserted] = track_of_root.emplace(root, tracks.size());
    if (inserted) tracks.emplace_back();
    tracks[it->second].push_back(k);
  }
  return tracks;
}

}  // namespace lmb
