#include "slam/loop/vocabulary_io.h"

#include <cstring>
#include <stdexcept>

#include "slam/common/byte_codec.h"
#include "slam/common/error.h"

namespace pcr {
namespace {

constexpr std::string_view kMagic = kVocabularyMagic;
constexpr size_t kHeaderBytes = 36;
constexpr size_t kNodeBytes = 48;
constexpr size_t kChecksumBytes = 8;

}  // namespace

uint64_t VocabularyFingerprint(const Vocabulary& vocabulary) {
  const std::vector<uint8_t> bytes = SerializeVocabulary(vocabulary);
  return Fnv1a64(bytes.data(), bytes.size());
}

std::vector<uint8_t> SerializeVocabulary(const Vocabulary& vocabulary) {
  const VocabularyOptions& o = vocabulary.options();
  const std::vector<Vocabulary::Node>& nodes = vocabulary.nodes();
  std::vector<uint8_t> out;
  out.reserve(kHeaderBytes + nodes.size() * kNodeBytes + kChecksumBytes);
  out.insert(out.end(), kMagic.begin(), kMagic.end());
  PutLittleEndian(kVocabularyFormatVersion, 2, &out);
  PutLittleEndian(static_cast<uint32_t>(o.branching), 4, &out);
  PutLittleEndian(static_cast<uint32_t>(o.depth), 4, &out);
  PutLittleEndian(static_cast<uint32_t>(o.max_iterations), 4, &out);
  PutLittleEndian(o.seed, 8, &out);
  PutLittleEndian(nodes.size(), 4, &out);
  PutLittleEndian(vocabulary.num_words(), 4, &out);
  for (const Vocabulary::Node& node : nodes) {
    PutLittleEndian(node.parent, 4, &out);
    for (uint64_t word : node.descriptor) PutLittleEndian(word, 8, &out);
    PutLittleEndian(node.word, 4, &out);
    PutLittleEndian(DoubleBits(node.idf_weight), 8, &out);
  }
  PutLittleEndian(Fnv1a64(out.data(), out.size()), 8, &out);
  return out;
}

Vocabulary DeserializeVocabulary(const uint8_t* data, size_t size, const std::string& name) {
  auto fail = [&name](const std::string& reason) { throw InputError(name, 0, reason); };
  if (size < kMagic.size() || std::memcmp(data, kMagic.data(), kMagic.size()) != 0)
    fail("not a PCR-ORB vocabulary (no PCRVOC magic)");
  if (size < kHeaderBytes + kChecksumBytes) {
    fail("truncated vocabulary: " + std::to_string(size) + " bytes, a header needs " +
         std::to_string(kHeaderBytes + kChecksumBytes));
  }
  const uint64_t version = GetLittleEndian(data + 6, 2);
  if (version != kVocabularyFormatVersion) {
    fail("unsupported vocabulary format version " + std::to_string(version) +
         " (this build reads " + std::to_string(kVocabularyFormatVersion) + ")");
  }
  VocabularyOptions options;
  options.branching = static_cast<int32_t>(GetLittleEndian(data + 8, 4));
  options.depth = static_cast<int32_t>(GetLittleEndian(data + 12, 4));
  options.max_iterations = static_cast<int32_t>(GetLittleEndian(data + 16, 4));
  options.seed = GetLittleEndian(data + 20, 8);
  const uint64_t num_nodes = GetLittleEndian(data + 28, 4);
  const uint64_t num_words = GetLittleEndian(data + 32, 4);
  const uint64_t expected = kHeaderBytes + num_nodes * kNodeBytes + kChecksumBytes;
  if (size != expected) {
    fail((size < expected ? "truncated vocabulary: " : "trailing bytes after the vocabulary: ") +
         std::to_string(size) + " bytes, " + std::to_string(num_nodes) + " nodes need " +
         std::to_string(expected));
  }
  const uint64_t stored = GetLittleEndian(data + size - kChecksumBytes, 8);
  const uint64_t computed = Fnv1a64(data, size - kChecksumBytes);
  if (stored != computed) fail("checksum mismatch: the vocabulary file is corrupted");

  std::vector<Vocabulary::Node> nodes(num_nodes);
  const uint8_t* p = data + kHeaderBytes;
  for (Vocabulary::Node& node : nodes) {
    node.parent = static_cast<NodeId>(GetLittleEndian(p, 4));
    for (int w = 0; w < 4; ++w) node.descriptor[w] = GetLittleEndian(p + 4 + 8 * w, 8);
    node.word = static_cast<WordId>(GetLittleEndian(p + 36, 4));
    node.idf_weight = BitsDouble(GetLittleEndian(p + 40, 8));
    p += kNodeBytes;
  }
  Vocabulary vocabulary;
  try {
    vocabulary = Vocabulary::FromNodes(options, std::move(nodes));
  } catch (const std::invalid_argument& e) {
    fail(std::string("inconsistent vocabulary tree: ") + e.what());
  }
  if (vocabulary.num_words() != num_words) {
    fail("inconsistent vocabulary tree: header says " + std::to_string(num_words) +
         " words, the tree has " + std::to_string(vocabulary.num_words()));
  }
  return vocabulary;
}

}  // namespace pcr
