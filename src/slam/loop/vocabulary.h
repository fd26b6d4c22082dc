#pragma once
// A vocabulary of binary words for place recognition (a bag of words in the manner of DBoW2,
// written for this project's 256-bit ORB descriptors, slam/features/orb_extractor.h).
//
// The vocabulary is a tree of `branching` children per node and at most `depth` levels below the
// root, trained by hierarchical k-medians in Hamming space; its leaves are the words. A
// descriptor is quantised by descending from the root to the nearest child (Hamming distance,
// ties to the lower node id) until a leaf. Words carry an IDF weight log(N / n_w) over the N
// training images with at least one descriptor, n_w of which have a descriptor that Transform
// puts in the word.
//
// Node layout: node 0 is the root (no descriptor); every other node's parent has a lower id, and
// the children of a node are listed in increasing id (Train allocates them contiguously, breadth
// first). Leaves carry word ids 0..num_words()-1 in increasing node id; inner nodes carry none.
//
// Pure and deterministic: Train gives bit-identical vocabularies for the same input and options
// on every platform (its own integer sampling on std::mt19937_64, no floating point in the tree).
// Thread-compatible: all const methods may be called concurrently.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

namespace pcr {

using WordId = uint32_t;
using NodeId = uint32_t;
inline constexpr NodeId kNoNode = std::numeric_limits<NodeId>::max();
inline constexpr WordId kNoWord = std::numeric_limits<WordId>::max();

// A bag of words: (word id, weight) sorted by increasing word id, each word once, weights the
// summed TF-IDF of the image's descriptors in that word, L1-normalised (they sum to 1; empty when
// no descriptor fell into a word of positive weight).
struct BowVector {
  std::vector<std::pair<WordId, double>> words;

  bool empty() const { return words.empty(); }
  size_t size() const { return words.size(); }
};

// Direct index: for each node at `levels_up` levels above the leaves, the indices (rows of the
// descriptor matrix, increasing) of the descriptors that descended through it; sorted by
// increasing node id. Used to restrict descriptor matching to descriptors of the same node.
struct FeatureVector {
  std::vector<std::pair<NodeId, std::vector<int>>> nodes;

  bool empty() const { return nodes.empty(); }
  size_t size() const { return nodes.size(); }
};

struct VocabularyOptions {
  int branching = 10;       // k: children per node, >= 2
  int depth = 4;            // L: levels below the root, >= 1 (at most branching^depth words)
  int max_iterations = 10;  // k-medians iterations per node, >= 1
  uint64_t seed = 1;        // seeds the k-means++ sampling

  bool IsValid(std::string* why) const;
};

class Vocabulary {
 public:
  using Descriptor = std::array<uint64_t, 4>;  // 256 bits, byte i of the row in bits 8*(i%8)..

  struct Node {
    NodeId parent = kNoNode;       // kNoNode for the root only
    Descriptor descriptor{};       // the cluster's bitwise median (all zero for the root)
    WordId word = kNoWord;         // leaves only
    double idf_weight = 0;         // leaves only: log(N / n_w) >= 0
    std::vector<NodeId> children;  // increasing id; empty for leaves
  };

  Vocabulary() = default;  // empty: no words; Transform gives empty vectors

  // Trains on one descriptor matrix per image (N x 32 CV_8U, N may be 0). Throws ConfigError
  // when options are invalid and std::invalid_argument when a matrix has another type or width,
  // or when there is no descriptor at all. Nodes with fewer distinct descriptors than
  // `branching` get one child per distinct descriptor; a node whose descriptors are all equal is
  // a leaf, so the tree may be shallower and have fewer words than branching^depth.
  static Vocabulary Train(const std::vector<cv::Mat>& descriptors_per_image,
                          const VocabularyOptions& options);

  // A vocabulary from its nodes (node.children is ignored and rebuilt from the parents), e.g. as
  // read back from a file. Throws std::invalid_argument naming the first inconsistency: invalid
  // options, no root, a parent that is not lower, a node with more than `branching` children or
  // deeper than `depth`, word ids not 0..W-1 on the leaves in increasing node id, a word on an
  // inner node, a negative or non-finite weight.
  static Vocabulary FromNodes(const VocabularyOptions& options, std::vector<Node> nodes);

  // Quantises each row of `descriptors` (N x 32 CV_8U; throws std::invalid_argument otherwise)
  // into `bow` (cleared first). Rows with (*skip)[i] != 0 are left out of both outputs (skip may
  // be null; otherwise it must hold N entries, else std::invalid_argument). `features` (may be
  // null) gets the direct index at the node `levels_up` levels above the leaves, i.e. at depth
  // max(0, depth() - levels_up) from the root, or the leaf itself when the leaf is shallower.
  // Words of zero weight are left out of both outputs.
  void Transform(const cv::Mat& descriptors, const std::vector<uint8_t>* skip, int levels_up,
                 BowVector* bow, FeatureVector* features) const;
  // The word of one descriptor (32 bytes) and, when node_at_depth >= 0 and node is not null, the
  // node at that depth on its path (the leaf when shallower). kNoWord on an empty vocabulary.
  WordId Quantise(const uint8_t* descriptor, int node_at_depth, NodeId* node) const;

  // DBoW2's L1 score of two L1-normalised vectors: 1 - 0.5 * |a - b|_1, in [0, 1]; 1 for equal
  // non-empty vectors, 0 when they share no word or either is empty.
  static double Score(const BowVector& a, const BowVector& b);

  bool empty() const { return words_.empty(); }
  size_t num_words() const { return words_.size(); }
  size_t num_nodes() const { return nodes_.size(); }
  int branching() const { return options_.branching; }
  int depth() const { return options_.depth; }
  const VocabularyOptions& options() const { return options_; }
  const std::vector<Node>& nodes() const { return nodes_; }
  NodeId word_node(WordId word) const { return words_[word]; }
  double word_weight(WordId word) const { return nodes_[words_[word]].idf_weight; }

 private:
  // Quantise on a packed descriptor of a non-empty vocabulary.
  WordId Descend(const Descriptor& d, int node_at_depth, NodeId* node) const;

  VocabularyOptions options_;
  std::vector<Node> nodes_;
  std::vector<NodeId> words_;    // word id -> leaf node id
  std::vector<int> node_depth_;  // per node, root 0
  // The children of every node in one array (compressed rows, for a cache-friendly descent):
  // node i's children are child_ids_[child_begin_[i] .. child_begin_[i + 1]), their descriptors
  // child_descriptors_ at the same positions.
  std::vector<uint32_t> child_begin_;
  std::vector<NodeId> child_ids_;
  std::vector<Descriptor> child_descriptors_;
};

// Packs a 32-byte descriptor (little-endian 64-bit words).
Vocabulary::Descriptor PackDescriptor(const uint8_t* bytes);

// The L1 score in two parts, so that a score summed word by word elsewhere
// (KeyframeDatabase::Scores) stays bit-equal to Vocabulary::Score: one shared word's term, with
// the two vectors' weights a and b of that word, and the score from the sum of the terms taken
// in increasing word order.
inline double L1ScoreTerm(double a, double b) {
  return std::abs(a) + std::abs(b) - std::abs(a - b);
}
inline double L1ScoreOfSum(double sum) { return std::clamp(0.5 * sum, 0.0, 1.0); }

inline int HammingDistance(const Vocabulary::Descriptor& a, const Vocabulary::Descriptor& b) {
  return __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) +
         __builtin_popcountll(a[2] ^ b[2]) + __builtin_popcountll(a[3] ^ b[3]);
}

}  // namespace pcr
