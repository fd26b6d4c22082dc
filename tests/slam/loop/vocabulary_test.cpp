#include "slam/loop/vocabulary.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "slam/common/error.h"
#include "slam/features/orb_extractor.h"
#include "slam/loop/vocabulary_io.h"
#include "support/data_paths.h"

namespace pcr {
namespace {

// ORB descriptors (default options) of a KITTI odometry left frame, cached per process.
const cv::Mat& KittiDescriptors(const std::string& sequence, int frame) {
  static std::map<std::pair<std::string, int>, cv::Mat> cache;
  auto it = cache.find({sequence, frame});
  if (it == cache.end()) {
    char name[64];
    std::snprintf(name, sizeof name, "data/kitti/sequences/%s/image_0/%06d.png", sequence.c_str(),
                  frame);
    const cv::Mat grey = cv::imread(test::SharedPath(name), cv::IMREAD_GRAYSCALE);
    EXPECT_FALSE(grey.empty()) << name;
    static const OrbExtractor extractor{OrbOptions()};
    cv::Mat descriptors = grey.empty() ? cv::Mat() : extractor.Extract(grey).descriptors;
    it = cache.emplace(std::make_pair(sequence, frame), descriptors).first;
  }
  return it->second;
}

Vocabulary TinyVocabulary() {
  VocabularyOptions options;
  options.branching = 4;
  options.depth = 3;
  return Vocabulary::Train(
      {KittiDescriptors("06", 0), KittiDescriptors("07", 0), KittiDescriptors("00", 0)}, options);
}

// A vocabulary large enough to tell places apart: k=8, L=3 on frames of three sequences.
const Vocabulary& SmallVocabulary() {
  static const Vocabulary vocabulary = [] {
    VocabularyOptions options;
    options.branching = 8;
    options.depth = 3;
    return Vocabulary::Train(
        {KittiDescriptors("06", 0), KittiDescriptors("06", 30), KittiDescriptors("07", 0),
         KittiDescriptors("07", 100), KittiDescriptors("00", 0), KittiDescriptors("00", 60)},
        options);
  }();
  return vocabulary;
}

BowVector Bow(const Vocabulary& v, const cv::Mat& descriptors) {
  BowVector bow;
  v.Transform(descriptors, nullptr, 0, &bow, nullptr);
  return bow;
}

std::vector<uint8_t> ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteBytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

// Reads a file as the driver's LoadVocabulary does (that one lives above src/slam).
Vocabulary LoadFile(const std::string& path) {
  const std::vector<uint8_t> bytes = ReadBytes(path);
  return DeserializeVocabulary(bytes.data(), bytes.size(), path);
}

// The InputError message of loading path, or "" when it loads.
std::string LoadError(const std::string& path) {
  try {
    LoadFile(path);
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path);
    return e.what();
  }
  return "";
}

TEST(VocabularyOptions, Validation) {
  std::string why;
  EXPECT_TRUE(VocabularyOptions().IsValid(&why)) << why;
  VocabularyOptions o;
  o.branching = 1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("branching"), std::string::npos);
  o = VocabularyOptions();
  o.depth = 0;
  EXPECT_FALSE(o.IsValid(&why));
  o = VocabularyOptions();
  o.branching = 100;
  o.depth = 5;  // 10^10 words
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THROW(Vocabulary::Train({KittiDescriptors("06", 0)}, o), ConfigError);
  EXPECT_THROW(Vocabulary::Train({cv::Mat()}, VocabularyOptions()), std::invalid_argument);
  EXPECT_THROW(Vocabulary::Train({cv::Mat::zeros(4, 16, CV_8U)}, VocabularyOptions()),
               std::invalid_argument);
}

TEST(Vocabulary, TrainingIsBitDeterministic) {
  const Vocabulary a = TinyVocabulary();
  const Vocabulary b = TinyVocabulary();
  EXPECT_GT(a.num_words(), 16u);
  EXPECT_LE(a.num_words(), 64u);
  EXPECT_EQ(a.branching(), 4);
  EXPECT_EQ(a.depth(), 3);
  EXPECT_EQ(SerializeVocabulary(a), SerializeVocabulary(b));
  // Another seed gives another tree.
  VocabularyOptions other;
  other.branching = 4;
  other.depth = 3;
  other.seed = 2;
  const Vocabulary c = Vocabulary::Train(
      {KittiDescriptors("06", 0), KittiDescriptors("07", 0), KittiDescriptors("00", 0)}, other);
  EXPECT_NE(SerializeVocabulary(a), SerializeVocabulary(c));
}

TEST(Vocabulary, TreeLayout) {
  const Vocabulary v = TinyVocabulary();
  const std::vector<Vocabulary::Node>& nodes = v.nodes();
  EXPECT_EQ(nodes[0].parent, kNoNode);
  WordId next_word = 0;
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (i > 0) {
      EXPECT_LT(nodes[i].parent, i);
    }
    EXPECT_LE(nodes[i].children.size(), 4u);
    if (nodes[i].children.empty()) {
      EXPECT_EQ(nodes[i].word, next_word++);
      EXPECT_GE(nodes[i].idf_weight, 0.0);
      EXPECT_LE(nodes[i].idf_weight, std::log(3.0) + 1e-12);
    } else {
      EXPECT_EQ(nodes[i].word, kNoWord);
    }
  }
  EXPECT_EQ(next_word, v.num_words());
}

TEST(Vocabulary, TransformIsNormalisedAndScoresPlaces) {
  const Vocabulary& v = SmallVocabulary();
  ASSERT_GT(v.num_words(), 200u);
  const BowVector frame = Bow(v, KittiDescriptors("06", 10));
  ASSERT_FALSE(frame.empty());
  double sum = 0;
  for (size_t i = 0; i < frame.words.size(); ++i) {
    if (i > 0) {
      EXPECT_LT(frame.words[i - 1].first, frame.words[i].first);
    }
    EXPECT_GT(frame.words[i].second, 0.0);
    sum += frame.words[i].second;
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_NEAR(Vocabulary::Score(frame, frame), 1.0, 1e-12);
  EXPECT_EQ(Vocabulary::Score(frame, BowVector()), 0.0);
  const double neighbour = Vocabulary::Score(frame, Bow(v, KittiDescriptors("06", 11)));
  const double other_sequence = Vocabulary::Score(frame, Bow(v, KittiDescriptors("07", 10)));
  const double other_place = Vocabulary::Score(frame, Bow(v, KittiDescriptors("06", 45)));
  EXPECT_GT(neighbour, other_sequence);
  EXPECT_GT(neighbour, other_place);
  EXPECT_GE(other_sequence, 0.0);
  EXPECT_LE(neighbour, 1.0);
  std::printf("k=8 L=3 scores: neighbour %.3f, 35 frames on %.3f, other sequence %.3f\n", neighbour,
              other_place, other_sequence);
}

TEST(Vocabulary, SkipDropsRowsAndFeatureVectorIndexesNodes) {
  const Vocabulary& v = SmallVocabulary();
  const cv::Mat& descriptors = KittiDescriptors("00", 20);
  ASSERT_GT(descriptors.rows, 100);
  std::vector<uint8_t> skip(descriptors.rows, 0);
  cv::Mat kept;
  for (int r = 0; r < descriptors.rows; ++r) {
    skip[r] = r % 3 == 0;
    if (!skip[r]) kept.push_back(descriptors.row(r));
  }
  BowVector with_skip;
  FeatureVector features;
  v.Transform(descriptors, &skip, 1, &with_skip, &features);
  const BowVector subset = Bow(v, kept);
  ASSERT_EQ(with_skip.words.size(), subset.words.size());
  for (size_t i = 0; i < subset.words.size(); ++i) {
    EXPECT_EQ(with_skip.words[i].first, subset.words[i].first);
    EXPECT_NEAR(with_skip.words[i].second, subset.words[i].second, 1e-12);
  }
  // The direct index holds no skipped row, each kept row once, at nodes of depth L - 1 = 2.
  std::vector<int> seen(descriptors.rows, 0);
  for (size_t i = 0; i < features.nodes.size(); ++i) {
    const auto& [node, rows] = features.nodes[i];
    if (i > 0) {
      EXPECT_LT(features.nodes[i - 1].first, node);
    }
    int depth = 0;
    for (NodeId n = node; v.nodes()[n].parent != kNoNode; n = v.nodes()[n].parent) ++depth;
    EXPECT_TRUE(depth == 2 || v.nodes()[node].children.empty()) << node;
    for (size_t j = 0; j < rows.size(); ++j) {
      if (j > 0) {
        EXPECT_LT(rows[j - 1], rows[j]);
      }
      EXPECT_FALSE(skip[rows[j]]);
      ++seen[rows[j]];
      NodeId word_node;
      v.Quantise(descriptors.ptr<uint8_t>(rows[j]), 2, &word_node);
      EXPECT_EQ(word_node, node);
    }
  }
  // Every kept row is indexed unless its word has zero weight (in every training image).
  for (int r = 0; r < descriptors.rows; ++r) {
    const WordId word = v.Quantise(descriptors.ptr<uint8_t>(r), -1, nullptr);
    EXPECT_EQ(seen[r], !skip[r] && v.word_weight(word) > 0 ? 1 : 0) << r;
  }
  // Everything skipped: empty outputs; a wrong skip size throws.
  std::fill(skip.begin(), skip.end(), 1);
  v.Transform(descriptors, &skip, 1, &with_skip, &features);
  EXPECT_TRUE(with_skip.empty());
  EXPECT_TRUE(features.empty());
  skip.pop_back();
  EXPECT_THROW(v.Transform(descriptors, &skip, 1, &with_skip, nullptr), std::invalid_argument);
}

// The shipped vocabulary (k=10, L=4) on a full KITTI frame, with the direct index at the loop
// closer's level (LoopClosingOptions::direct_index_levels_up = 2): the bag of words and the direct
// index are what Quantise gives row by row, and they do not depend on the order of the rows (the
// bag bit for bit, the direct index up to the renumbering of the rows).
TEST(Vocabulary, ShippedVocabularyTransformAgreesWithQuantiseRowByRow) {
  const Vocabulary v = LoadFile(std::string(PCR_SOURCE_DIR) + "/vocabulary/pcr_orb_voc.bin");
  const cv::Mat& descriptors = KittiDescriptors("07", 50);
  ASSERT_GE(descriptors.rows, 1900);
  constexpr int kLevelsUp = 2;
  BowVector bow;
  FeatureVector features;
  v.Transform(descriptors, nullptr, kLevelsUp, &bow, &features);

  // Row by row: the weights of each word summed and L1-normalised; each row of positive weight
  // listed, in increasing order, under its node at depth L - 2.
  std::map<WordId, double> word_sums;
  std::map<NodeId, std::vector<int>> rows_of_node;
  double total = 0;
  for (int r = 0; r < descriptors.rows; ++r) {
    NodeId node = kNoNode;
    const WordId word = v.Quantise(descriptors.ptr<uint8_t>(r), v.depth() - kLevelsUp, &node);
    ASSERT_NE(word, kNoWord);
    if (v.word_weight(word) <= 0) continue;
    word_sums[word] += v.word_weight(word);
    total += v.word_weight(word);
    rows_of_node[node].push_back(r);
  }
  ASSERT_GT(word_sums.size(), 500u);
  ASSERT_EQ(bow.size(), word_sums.size());
  size_t i = 0;
  for (const auto& [word, sum] : word_sums) {
    EXPECT_EQ(bow.words[i].first, word) << i;
    EXPECT_NEAR(bow.words[i].second, sum / total, 1e-12) << "word " << word;
    ++i;
  }
  ASSERT_EQ(features.size(), rows_of_node.size());
  i = 0;
  for (const auto& [node, rows] : rows_of_node) {
    EXPECT_EQ(features.nodes[i].first, node) << i;
    EXPECT_EQ(features.nodes[i].second, rows) << "node " << node;
    ++i;
  }

  // The rows in reverse order: the same bag of words bit for bit; the same direct index with row
  // r renumbered n - 1 - r.
  cv::Mat reversed;
  cv::flip(descriptors, reversed, 0);
  BowVector bow_reversed;
  FeatureVector features_reversed;
  v.Transform(reversed, nullptr, kLevelsUp, &bow_reversed, &features_reversed);
  EXPECT_EQ(bow_reversed.words, bow.words);
  ASSERT_EQ(features_reversed.size(), features.size());
  for (size_t k = 0; k < features.size(); ++k) {
    EXPECT_EQ(features_reversed.nodes[k].first, features.nodes[k].first);
    std::vector<int> back;
    for (int r : features_reversed.nodes[k].second) back.push_back(descriptors.rows - 1 - r);
    std::sort(back.begin(), back.end());
    EXPECT_EQ(back, features.nodes[k].second) << "node " << features.nodes[k].first;
  }
}

TEST(VocabularyIo, RoundTripGivesTheSameBytes) {
  const Vocabulary v = TinyVocabulary();
  const std::vector<uint8_t> bytes = SerializeVocabulary(v);
  EXPECT_EQ(bytes.size(), 36 + 48 * v.num_nodes() + 8);
  const std::string path = test::MakeTempDir("vocabulary") + "/tiny.bin";
  WriteBytes(path, bytes);
  const Vocabulary back = LoadFile(path);
  EXPECT_EQ(SerializeVocabulary(back), bytes);
  EXPECT_EQ(back.num_words(), v.num_words());
  const cv::Mat& descriptors = KittiDescriptors("06", 5);
  const BowVector a = Bow(v, descriptors), b = Bow(back, descriptors);
  EXPECT_EQ(a.words, b.words);
}

TEST(VocabularyIo, BadFilesThrowInputErrorNamingTheFile) {
  const std::vector<uint8_t> bytes = SerializeVocabulary(TinyVocabulary());
  const std::string dir = test::MakeTempDir("vocabulary_bad");

  const std::string truncated = dir + "/truncated.bin";
  WriteBytes(truncated, std::vector<uint8_t>(bytes.begin(), bytes.begin() + bytes.size() / 2));
  EXPECT_NE(LoadError(truncated).find("truncated"), std::string::npos) << LoadError(truncated);
  WriteBytes(truncated, std::vector<uint8_t>(bytes.begin(), bytes.begin() + 20));
  EXPECT_NE(LoadError(truncated).find("truncated"), std::string::npos) << LoadError(truncated);

  const std::string empty = dir + "/empty.bin";
  WriteBytes(empty, {});
  EXPECT_NE(LoadError(empty).find("magic"), std::string::npos) << LoadError(empty);

  std::vector<uint8_t> foreign = bytes;
  foreign[0] = 'X';
  const std::string wrong_magic = dir + "/foreign.bin";
  WriteBytes(wrong_magic, foreign);
  EXPECT_NE(LoadError(wrong_magic).find("magic"), std::string::npos) << LoadError(wrong_magic);

  std::vector<uint8_t> future = bytes;
  future[6] = 9;
  const std::string version = dir + "/version.bin";
  WriteBytes(version, future);
  EXPECT_NE(LoadError(version).find("version 9"), std::string::npos) << LoadError(version);

  std::vector<uint8_t> flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  const std::string corrupted = dir + "/corrupted.bin";
  WriteBytes(corrupted, flipped);
  EXPECT_NE(LoadError(corrupted).find("checksum"), std::string::npos) << LoadError(corrupted);

  // A consistent checksum over an inconsistent tree: node 1's parent made itself.
  std::vector<uint8_t> bad_tree = bytes;
  bad_tree[36 + 48] = 1;
  bad_tree.resize(bad_tree.size() - 8);
  const uint64_t sum = Fnv1a64(bad_tree.data(), bad_tree.size());
  for (int i = 0; i < 8; ++i) bad_tree.push_back(static_cast<uint8_t>(sum >> (8 * i)));
  const std::string tree = dir + "/tree.bin";
  WriteBytes(tree, bad_tree);
  EXPECT_NE(LoadError(tree).find("inconsistent vocabulary tree: vocabulary: node 1 has parent 1"),
            std::string::npos)
      << LoadError(tree);

  // The message names the file.
  EXPECT_NE(LoadError(corrupted).find(corrupted), std::string::npos);
}

TEST(VocabularyIo, ShippedVocabularyLoadsAndTellsPlacesApart) {
  const Vocabulary v = LoadFile(std::string(PCR_SOURCE_DIR) + "/vocabulary/pcr_orb_voc.bin");
  EXPECT_EQ(v.branching(), 10);
  EXPECT_EQ(v.depth(), 4);
  EXPECT_GT(v.num_words(), 5000u);
  // Over frames of sequence 00 (0.4 s apart in the training set at most), the next frame scores
  // well above a frame 4 s on and a frame of sequence 07.
  double neighbour = 0, other_place = 0, other_sequence = 0;
  for (int f : {15, 35, 55}) {
    const BowVector frame = Bow(v, KittiDescriptors("00", f));
    neighbour += Vocabulary::Score(frame, Bow(v, KittiDescriptors("00", f + 2)));
    other_place += Vocabulary::Score(frame, Bow(v, KittiDescriptors("00", f + 40)));
    other_sequence += Vocabulary::Score(frame, Bow(v, KittiDescriptors("07", f)));
  }
  std::printf(
      "shipped k=10 L=4 mean scores: 2 frames on %.3f, 40 frames on %.3f, other sequence "
      "%.3f\n",
      neighbour / 3, other_place / 3, other_sequence / 3);
  EXPECT_GT(neighbour, 1.3 * other_place);
  EXPECT_GT(neighbour, 1.3 * other_sequence);
}

}  // namespace
}  // namespace pcr
