#pragma once
// Damaged copies of real ONNX models for tests of bad input: a protobuf re-serialiser that keeps
// the file well-formed while one tensor's data no longer matches its dims.
#include <string>

#include "support/onnx_writer.h"

namespace pcr::test {

// The serialized ModelProto with the raw_data of initializer `tensor` cut to its first half
// (the length prefixes of the tensor and the graph follow). Throws std::runtime_error when the
// bytes are not a protobuf or the graph has no such initializer.
Bytes HalveRawData(const Bytes& model, const std::string& tensor);

// The shipped 224x640 YOLOv8n-seg model with the raw_data of kDamagedTensor (64x64x2x2 floats)
// halved, written to a file in a fresh temp dir; returns the file's path.
inline constexpr const char* kDamagedTensor = "model.22.proto.upsample.weight";
std::string WriteDamagedYoloModel();

}  // namespace pcr::test
