#pragma once
// Little-endian binary encoding for the project's file formats (the vocabulary, the saved map):
// a writer appending to a byte vector and a bounds-checked reader that throws InputError naming
// the buffer (the file) and the byte offset when the data runs out. Pure: no files.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "slam/common/error.h"

namespace pcr {

// FNV-1a 64 of size bytes.
uint64_t Fnv1a64(const uint8_t* data, size_t size);

// Appends v's low `bytes` bytes, least significant first.
inline void PutLittleEndian(uint64_t v, int bytes, std::vector<uint8_t>* out) {
  for (int i = 0; i < bytes; ++i) out->push_back(static_cast<uint8_t>(v >> (8 * i)));
}

inline uint64_t GetLittleEndian(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
  return v;
}

inline uint64_t DoubleBits(double d) {
  uint64_t bits;
  std::memcpy(&bits, &d, sizeof bits);
  return bits;
}

inline double BitsDouble(uint64_t bits) {
  double d;
  std::memcpy(&d, &bits, sizeof d);
  return d;
}

class ByteWriter {
 public:
  void U8(uint8_t v) { bytes_.push_back(v); }
  void U16(uint16_t v) { PutLittleEndian(v, 2, &bytes_); }
  void U32(uint32_t v) { PutLittleEndian(v, 4, &bytes_); }
  void U64(uint64_t v) { PutLittleEndian(v, 8, &bytes_); }
  void I32(int32_t v) { PutLittleEndian(static_cast<uint32_t>(v), 4, &bytes_); }
  void I64(int64_t v) { PutLittleEndian(static_cast<uint64_t>(v), 8, &bytes_); }
  void F32(float v) {
    uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    U32(bits);
  }
  void F64(double v) { U64(DoubleBits(v)); }
  void Raw(const void* data, size_t size) {
    const auto* p = static_cast<const uint8_t*>(data);
    bytes_.insert(bytes_.end(), p, p + size);
  }
  // Appends FNV-1a 64 of everything written so far.
  void Checksum() { U64(Fnv1a64(bytes_.data(), bytes_.size())); }
  size_t size() const { return bytes_.size(); }
  std::vector<uint8_t>& bytes() { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
};

class ByteReader {
 public:
  // name: what errors name (the file path).
  ByteReader(const uint8_t* data, size_t size, std::string name)
      : data_(data), size_(size), name_(std::move(name)) {}

  uint8_t U8() { return static_cast<uint8_t>(Get(1)); }
  uint16_t U16() { return static_cast<uint16_t>(Get(2)); }
  uint32_t U32() { return static_cast<uint32_t>(Get(4)); }
  uint64_t U64() { return Get(8); }
  int32_t I32() { return static_cast<int32_t>(static_cast<uint32_t>(Get(4))); }
  int64_t I64() { return static_cast<int64_t>(Get(8)); }
  float F32() {
    const uint32_t bits = U32();
    float v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }
  double F64() { return BitsDouble(Get(8)); }
  void Raw(void* out, size_t size) {
    Need(size);
    std::memcpy(out, data_ + pos_, size);
    pos_ += size;
  }
  // A count of items of at least min_item_bytes each that must fit in the bytes left (so that a
  // corrupted count fails here instead of allocating without bound).
  size_t Count(size_t min_item_bytes, const char* what) {
    const uint64_t n = U64();
    if (min_item_bytes > 0 && n > remaining() / min_item_bytes)
      Fail(std::string("truncated or corrupted: ") + what + " count " + std::to_string(n) +
           " does not fit in the " + std::to_string(remaining()) + " bytes left");
    return static_cast<size_t>(n);
  }

  size_t position() const { return pos_; }
  size_t remaining() const { return size_ - pos_; }
  const std::string& name() const { return name_; }
  // Throws InputError(name, 0, reason + " (at byte N)").
  [[noreturn]] void Fail(const std::string& reason) const {
    throw InputError(name_, 0, reason + " (at byte " + std::to_string(pos_) + ")");
  }

 private:
  void Need(size_t n) const {
    if (n > remaining())
      Fail("truncated: " + std::to_string(n) + " more bytes needed, " +
           std::to_string(remaining()) + " left");
  }
  uint64_t Get(int bytes) {
    Need(static_cast<size_t>(bytes));
    const uint64_t v = GetLittleEndian(data_ + pos_, bytes);
    pos_ += static_cast<size_t>(bytes);
    return v;
  }

  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  std::string name_;
};

}  // namespace pcr
