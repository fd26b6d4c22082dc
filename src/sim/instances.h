#pragma once
// Object instances of the synthetic world and their per-pixel ground truth. Instance images are
// CV_16UC1: kStaticInstanceId for the static world (road, kerbs, buildings, poles), kSkyInstanceId
// for the sky, other values are object ids listed in instances.txt.
#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <ostream>
#include <string>
#include <vector>

namespace pcr::sim {

inline constexpr uint16_t kStaticInstanceId = 0;
inline constexpr uint16_t kSkyInstanceId = 65535;

// COCO-like classes.
enum class ObjectClass : uint8_t { kCar, kPerson, kBicycle };
const char* ClassName(ObjectClass object_class);
// Throws std::invalid_argument for another name.
ObjectClass ParseClassName(const std::string& name);

struct InstanceInfo {
  uint16_t id = 0;
  ObjectClass object_class = ObjectClass::kCar;
  bool moving = false;
  double speed_mps = 0;  // 0 for parked objects
  // Bounding box size in the object frame (x width, y height, z length), metres. The object
  // frame has its origin on the ground under the box centre, x right, y down, z forward.
  Eigen::Vector3d size_m = Eigen::Vector3d::Zero();
};

// Look-up of instance ids (e.g. for dynamic-point filter ground truth).
class InstanceTable {
 public:
  InstanceTable() = default;
  explicit InstanceTable(std::vector<InstanceInfo> instances);

  // nullptr for kStaticInstanceId, kSkyInstanceId and unknown ids.
  const InstanceInfo* Find(uint16_t id) const;
  bool IsObject(uint16_t id) const { return Find(id) != nullptr; }
  bool IsMoving(uint16_t id) const;
  // "background", "sky", a class name, or "unknown".
  std::string ClassNameOf(uint16_t id) const;
  const std::vector<InstanceInfo>& all() const { return instances_; }
  size_t size() const { return instances_.size(); }

  // instances.txt: '#' comment lines, then "id class moving speed_mps size_x size_y size_z".
  void Write(std::ostream& out) const;
  // Throws pcr::InputError naming the file and 1-based line.
  static InstanceTable Read(const std::string& path);

 private:
  std::vector<InstanceInfo> instances_;
  std::vector<int32_t> index_of_id_;  // id -> position in instances_, -1 when absent
};

// CV_8UC1 mask (255 where the pixel belongs to a moving instance) of a CV_16UC1 instance image.
cv::Mat MovingMask(const cv::Mat& instance_image, const InstanceTable& table);

}  // namespace pcr::sim
