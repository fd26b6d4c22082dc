#include "slam/loop/vocabulary.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <random>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/popcount_clones.h"

namespace pcr {
namespace {

constexpr int kDescriptorBytes = 32;
// Most words a vocabulary may have (branching^depth): keeps node ids and training memory sane.
constexpr double kMaxWords = 16777216.0;  // 2^24

// A value in [0, n) from the generator; n > 0. Modulo, not std::uniform_int_distribution, whose
// output is implementation-defined: this keeps training bit-identical across standard libraries.
uint64_t RandomBelow(std::mt19937_64& rng, uint64_t n) { return rng() % n; }

void CheckDescriptorMatrix(const cv::Mat& descriptors, const char* what) {
  if (descriptors.empty()) return;
  if (descriptors.type() != CV_8UC1 || descriptors.cols != kDescriptorBytes) {
    throw std::invalid_argument(std::string(what) + ": descriptors must be N x 32 CV_8U, got " +
                                std::to_string(descriptors.rows) + " x " +
                                std::to_string(descriptors.cols) + " of type " +
                                std::to_string(descriptors.type()));
  }
}

// Descends from the root of a vocabulary in compressed-row form (see Vocabulary's members) to
// the nearest leaf; returns its node id and sets *at_depth to the node at depth node_at_depth on
// the way (the leaf when shallower), when at_depth is not null.
PCR_POPCNT_CLONES NodeId DescendTree(const uint32_t* child_begin, const NodeId* child_ids,
                                     const Vocabulary::Descriptor* child_descriptors,
                                     const Vocabulary::Descriptor& d, int node_at_depth,
                                     NodeId* at_depth) {
  NodeId id = 0;
  int depth = 0;
  if (at_depth && node_at_depth == 0) *at_depth = 0;
  while (child_begin[id] != child_begin[id + 1]) {
    const uint32_t begin = child_begin[id], end = child_begin[id + 1];
    uint32_t best = begin;
    int best_distance = HammingDistance(d, child_descriptors[begin]);
    for (uint32_t c = begin + 1; c < end; ++c) {
      const int distance = HammingDistance(d, child_descriptors[c]);
      if (distance < best_distance) {
        best_distance = distance;
        best = c;
      }
    }
    id = child_ids[best];
    ++depth;
    if (at_depth && depth == node_at_depth) *at_depth = id;
  }
  if (at_depth && depth < node_at_depth) *at_depth = id;
  return id;
}

// Bitwise majority of the members' descriptors (a bit is set when more than half have it set).
Vocabulary::Descriptor Majority(const std::vector<Vocabulary::Descriptor>& all,
                                const std::vector<uint32_t>& members) {
  std::array<uint32_t, 256> ones{};
  for (uint32_t m : members) {
    for (int w = 0; w < 4; ++w) {
      uint64_t bits = all[m][w];
      while (bits != 0) {
        ++ones[w * 64 + __builtin_ctzll(bits)];
        bits &= bits - 1;
      }
    }
  }
  Vocabulary::Descriptor centre{};
  for (int b = 0; b < 256; ++b) {
    if (2 * static_cast<uint64_t>(ones[b]) > members.size())
      centre[b / 64] |= uint64_t{1} << (b % 64);
  }
  return centre;
}

int Nearest(const Vocabulary::Descriptor& d, const std::vector<Vocabulary::Descriptor>& centres) {
  int best = 0, best_distance = HammingDistance(d, centres[0]);
  for (size_t c = 1; c < centres.size(); ++c) {
    const int distance = HammingDistance(d, centres[c]);
    if (distance < best_distance) {
      best_distance = distance;
      best = static_cast<int>(c);
    }
  }
  return best;
}

// k-medians of `members` (indices into all, increasing) with k-means++ seeding (probability
// proportional to the squared Hamming distance, integer sampling). Fewer than k clusters when
// the members have fewer distinct descriptors. Each returned cluster is non-empty and lists its
// members in increasing order; centres[c] is the bitwise median of the previous assignment and
// every member is assigned to its nearest centre (ties to the lower index).
PCR_POPCNT_CLONES void KMedians(const std::vector<Vocabulary::Descriptor>& all,
                                const std::vector<uint32_t>& members, int k, int max_iterations,
                                std::mt19937_64& rng, std::vector<Vocabulary::Descriptor>* centres,
                                std::vector<std::vector<uint32_t>>* clusters) {
  const size_t n = members.size();
  centres->clear();
  clusters->clear();
  if (n == 0) return;
  centres->push_back(all[members[RandomBelow(rng, n)]]);
  std::vector<uint64_t> distance2(n);
  for (size_t j = 0; j < n; ++j) {
    const uint64_t d = HammingDistance(all[members[j]], centres->back());
    distance2[j] = d * d;
  }
  while (static_cast<int>(centres->size()) < k) {
    uint64_t total = 0;
    for (uint64_t d2 : distance2) total += d2;
    if (total == 0) break;  // every member equals a centre
    const uint64_t r = RandomBelow(rng, total);
    uint64_t cumulative = 0;
    size_t pick = 0;
    for (; pick < n; ++pick) {
      cumulative += distance2[pick];
      if (cumulative > r) break;
    }
    centres->push_back(all[members[pick]]);
    for (size_t j = 0; j < n; ++j) {
      const uint64_t d = HammingDistance(all[members[j]], centres->back());
      distance2[j] = std::min(distance2[j], d * d);
    }
  }

  std::vector<int> assignment(n);
  for (size_t j = 0; j < n; ++j) assignment[j] = Nearest(all[members[j]], *centres);
  const int num_centres = static_cast<int>(centres->size());
  auto group = [&] {
    clusters->assign(num_centres, {});
    for (size_t j = 0; j < n; ++j) (*clusters)[assignment[j]].push_back(members[j]);
  };
  if (num_centres > 1) {
    for (int iteration = 0; iteration < max_iterations; ++iteration) {
      group();
      for (int c = 0; c < num_centres; ++c) {
        if (!(*clusters)[c].empty()) (*centres)[c] = Majority(all, (*clusters)[c]);
      }
      bool changed = false;
      for (size_t j = 0; j < n; ++j) {
        const int nearest = Nearest(all[members[j]], *centres);
        changed |= nearest != assignment[j];
        assignment[j] = nearest;
      }
      if (!changed) break;
    }
  }
  group();
  // Drop empty clusters (a centre that lost all its members).
  size_t kept = 0;
  for (size_t c = 0; c < clusters->size(); ++c) {
    if ((*clusters)[c].empty()) continue;
    if (kept != c) {
      (*centres)[kept] = (*centres)[c];
      (*clusters)[kept] = std::move((*clusters)[c]);
    }
    ++kept;
  }
  centres->resize(kept);
  clusters->resize(kept);
}

}  // namespace

Vocabulary::Descriptor PackDescriptor(const uint8_t* bytes) {
  Vocabulary::Descriptor d{};
  for (int i = 0; i < kDescriptorBytes; ++i)
    d[i / 8] |= static_cast<uint64_t>(bytes[i]) << (8 * (i % 8));
  return d;
}

bool VocabularyOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  if (branching < 2) return fail("branching must be >= 2, got " + std::to_string(branching));
  if (depth < 1) return fail("depth must be >= 1, got " + std::to_string(depth));
  if (max_iterations < 1)
    return fail("max_iterations must be >= 1, got " + std::to_string(max_iterations));
  if (std::pow(static_cast<double>(branching), depth) > kMaxWords) {
    return fail("branching^depth must be <= 2^24 words, got " + std::to_string(branching) + "^" +
                std::to_string(depth));
  }
  return true;
}

Vocabulary Vocabulary::Train(const std::vector<cv::Mat>& descriptors_per_image,
                             const VocabularyOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("VocabularyOptions: " + why);
  std::vector<Descriptor> all;
  std::vector<uint32_t> image_of;
  for (size_t i = 0; i < descriptors_per_image.size(); ++i) {
    const cv::Mat& m = descriptors_per_image[i];
    CheckDescriptorMatrix(m, "Vocabulary::Train");
    for (int r = 0; r < m.rows; ++r) {
      all.push_back(PackDescriptor(m.ptr<uint8_t>(r)));
      image_of.push_back(static_cast<uint32_t>(i));
    }
  }
  if (all.empty()) throw std::invalid_argument("Vocabulary::Train: no descriptors");

  std::vector<Node> nodes(1);
  struct Pending {
    NodeId node;
    int depth;
    std::vector<uint32_t> members;
  };
  std::deque<Pending> queue;
  {
    Pending root{0, 0, std::vector<uint32_t>(all.size())};
    for (size_t j = 0; j < all.size(); ++j) root.members[j] = static_cast<uint32_t>(j);
    queue.push_back(std::move(root));
  }
  std::mt19937_64 rng(options.seed);
  std::vector<Descriptor> centres;
  std::vector<std::vector<uint32_t>> clusters;
  while (!queue.empty()) {
    Pending p = std::move(queue.front());
    queue.pop_front();
    if (p.depth == options.depth) continue;
    KMedians(all, p.members, options.branching, options.max_iterations, rng, &centres, &clusters);
    if (clusters.size() <= 1) continue;  // all members equal: a leaf above the last level
    p.members = {};
    for (size_t c = 0; c < clusters.size(); ++c) {
      const NodeId id = static_cast<NodeId>(nodes.size());
      Node child;
      child.parent = p.node;
      child.descriptor = centres[c];
      nodes.push_back(child);
      queue.push_back({id, p.depth + 1, std::move(clusters[c])});
    }
  }
  // Words in increasing node id; weights from the images whose descriptors Transform puts there.
  WordId next_word = 0;
  std::vector<bool> inner(nodes.size(), false);
  for (size_t i = 1; i < nodes.size(); ++i) inner[nodes[i].parent] = true;
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (!inner[i]) nodes[i].word = next_word++;
  }
  Vocabulary vocabulary = FromNodes(options, std::move(nodes));

  std::vector<uint32_t> images_with_word(vocabulary.num_words(), 0);
  std::vector<uint32_t> last_image(vocabulary.num_words(), std::numeric_limits<uint32_t>::max());
  uint32_t num_images = 0, previous_image = std::numeric_limits<uint32_t>::max();
  for (size_t j = 0; j < all.size(); ++j) {
    if (image_of[j] != previous_image) ++num_images;
    previous_image = image_of[j];
    const WordId word = vocabulary.Descend(all[j], -1, nullptr);
    if (last_image[word] != image_of[j]) {
      last_image[word] = image_of[j];
      ++images_with_word[word];
    }
  }
  for (WordId w = 0; w < vocabulary.num_words(); ++w) {
    vocabulary.nodes_[vocabulary.words_[w]].idf_weight =
        images_with_word[w] == 0
            ? 0.0
            : std::log(static_cast<double>(num_images) / static_cast<double>(images_with_word[w]));
  }
  return vocabulary;
}

Vocabulary Vocabulary::FromNodes(const VocabularyOptions& options, std::vector<Node> nodes) {
  auto fail = [](const std::string& reason) {
    throw std::invalid_argument("vocabulary: " + reason);
  };
  std::string why;
  if (!options.IsValid(&why)) fail("invalid options: " + why);
  if (nodes.empty()) fail("no root node");
  if (nodes[0].parent != kNoNode) fail("node 0 (the root) has a parent");
  Vocabulary v;
  v.options_ = options;
  v.node_depth_.assign(nodes.size(), 0);
  for (Node& node : nodes) node.children.clear();
  for (size_t i = 1; i < nodes.size(); ++i) {
    const NodeId parent = nodes[i].parent;
    if (parent >= i) {
      fail("node " + std::to_string(i) + " has parent " +
           (parent == kNoNode ? std::string("none") : std::to_string(parent)) +
           ", not a lower node id");
    }
    nodes[parent].children.push_back(static_cast<NodeId>(i));
    if (static_cast<int>(nodes[parent].children.size()) > options.branching) {
      fail("node " + std::to_string(parent) + " has more than " +
           std::to_string(options.branching) + " children");
    }
    v.node_depth_[i] = v.node_depth_[parent] + 1;
    if (v.node_depth_[i] > options.depth) {
      fail("node " + std::to_string(i) + " is deeper than depth " + std::to_string(options.depth));
    }
  }
  for (size_t i = 0; i < nodes.size(); ++i) {
    const Node& node = nodes[i];
    if (node.children.empty()) {
      if (node.word != v.words_.size()) {
        fail("leaf node " + std::to_string(i) + " has word " +
             (node.word == kNoWord ? std::string("none") : std::to_string(node.word)) +
             ", expected " + std::to_string(v.words_.size()));
      }
      if (!std::isfinite(node.idf_weight) || node.idf_weight < 0) {
        fail("word " + std::to_string(node.word) + " has weight " +
             std::to_string(node.idf_weight) + ", not finite and >= 0");
      }
      v.words_.push_back(static_cast<NodeId>(i));
    } else if (node.word != kNoWord || node.idf_weight != 0) {
      fail("inner node " + std::to_string(i) + " carries a word or a weight");
    }
  }
  v.nodes_ = std::move(nodes);
  v.child_begin_.assign(1, 0);
  for (const Node& node : v.nodes_) {
    for (NodeId child : node.children) {
      v.child_ids_.push_back(child);
      v.child_descriptors_.push_back(v.nodes_[child].descriptor);
    }
    v.child_begin_.push_back(static_cast<uint32_t>(v.child_ids_.size()));
  }
  return v;
}

WordId Vocabulary::Quantise(const uint8_t* descriptor, int node_at_depth, NodeId* node) const {
  if (nodes_.empty()) return kNoWord;
  return Descend(PackDescriptor(descriptor), node_at_depth, node);
}

WordId Vocabulary::Descend(const Descriptor& d, int node_at_depth, NodeId* node) const {
  const NodeId leaf = DescendTree(child_begin_.data(), child_ids_.data(), child_descriptors_.data(),
                                  d, node_at_depth, node);
  return nodes_[leaf].word;
}

void Vocabulary::Transform(const cv::Mat& descriptors, const std::vector<uint8_t>* skip,
                           int levels_up, BowVector* bow, FeatureVector* features) const {
  if (bow == nullptr) throw std::invalid_argument("Vocabulary::Transform: bow is null");
  bow->words.clear();
  if (features) features->nodes.clear();
  CheckDescriptorMatrix(descriptors, "Vocabulary::Transform");
  if (skip && skip->size() != static_cast<size_t>(descriptors.rows)) {
    throw std::invalid_argument("Vocabulary::Transform: skip has " + std::to_string(skip->size()) +
                                " entries for " + std::to_string(descriptors.rows) + " rows");
  }
  if (empty() || descriptors.empty()) return;
  const int node_depth = std::max(0, options_.depth - levels_up);
  struct Hit {
    WordId word;
    NodeId node;
    int row;
  };
  std::vector<Hit> hits;
  hits.reserve(descriptors.rows);
  for (int r = 0; r < descriptors.rows; ++r) {
    if (skip && (*skip)[r] != 0) continue;
    Hit hit{0, 0, r};
    hit.word = Quantise(descriptors.ptr<uint8_t>(r), features ? node_depth : -1, &hit.node);
    if (nodes_[words_[hit.word]].idf_weight > 0) hits.push_back(hit);
  }
  if (hits.empty()) return;
  std::sort(hits.begin(), hits.end(), [](const Hit& a, const Hit& b) {
    return a.word != b.word ? a.word < b.word : a.row < b.row;
  });
  double sum = 0;
  for (const Hit& hit : hits) {
    const double weight = nodes_[words_[hit.word]].idf_weight;
    if (bow->words.empty() || bow->words.back().first != hit.word)
      bow->words.emplace_back(hit.word, 0.0);
    bow->words.back().second += weight;
    sum += weight;
  }
  for (auto& [word, weight] : bow->words) weight /= sum;
  if (features) {
    std::sort(hits.begin(), hits.end(), [](const Hit& a, const Hit& b) {
      return a.node != b.node ? a.node < b.node : a.row < b.row;
    });
    for (const Hit& hit : hits) {
      if (features->nodes.empty() || features->nodes.back().first != hit.node)
        features->nodes.emplace_back(hit.node, std::vector<int>());
      features->nodes.back().second.push_back(hit.row);
    }
  }
}

double Vocabulary::Score(const BowVector& a, const BowVector& b) {
  double sum = 0;
  auto i = a.words.begin(), j = b.words.begin();
  while (i != a.words.end() && j != b.words.end()) {
    if (i->first < j->first) {
      ++i;
    } else if (j->first < i->first) {
      ++j;
    } else {
      sum += L1ScoreTerm(i->second, j->second);
      ++i;
      ++j;
    }
  }
  return L1ScoreOfSum(sum);
}

}  // namespace pcr
