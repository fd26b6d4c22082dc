#pragma once
// The vocabulary's byte format (pure: no files; the driver reads and writes the bytes).
//
// Version 1, all integers little-endian, doubles as their IEEE-754 bits in a u64:
//   offset  0  "PCRVOC" (6 bytes), u16 format version
//           8  i32 branching, i32 depth, i32 max_iterations, u64 seed (VocabularyOptions)
//          28  u32 node count, u32 word count
//          36  per node, in node id order (48 bytes each): u32 parent id (0xFFFFFFFF for the
//              root), 32 bytes descriptor, u32 word id (0xFFFFFFFF for inner nodes),
//              f64 IDF weight (0 for inner nodes)
//         end  u64 FNV-1a 64 of every byte before it
// Children are implicit (the nodes whose parent is the node, in increasing id).
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "slam/common/byte_codec.h"  // Fnv1a64
#include "slam/loop/vocabulary.h"

namespace pcr {

inline constexpr uint16_t kVocabularyFormatVersion = 1;
// The first bytes of every file of this format.
inline constexpr std::string_view kVocabularyMagic = "PCRVOC";

// The bytes of the format above; deterministic (the same vocabulary gives the same bytes).
std::vector<uint8_t> SerializeVocabulary(const Vocabulary& vocabulary);

// FNV-1a 64 of those bytes: what a saved map's place section and a run's stats.json record.
uint64_t VocabularyFingerprint(const Vocabulary& vocabulary);

// Reads the format back. Throws pcr::InputError(name, 0, reason) on a foreign, truncated,
// corrupted or inconsistent buffer: too short for a header, wrong magic, unsupported version,
// size not matching the node count, checksum mismatch, or a tree Vocabulary::FromNodes refuses.
// `name` is what the error names (the file path).
Vocabulary DeserializeVocabulary(const uint8_t* data, size_t size, const std::string& name);

}  // namespace pcr
