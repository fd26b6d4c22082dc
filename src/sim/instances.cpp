#include "sim/instances.h"

#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "slam/common/error.h"

namespace pcr::sim {

const char* ClassName(ObjectClass object_class) {
  switch (object_class) {
    case ObjectClass::kCar:
      return "car";
    case ObjectClass::kPerson:
      return "person";
    case ObjectClass::kBicycle:
      return "bicycle";
  }
  return "unknown";
}

ObjectClass ParseClassName(const std::string& name) {
  if (name == "car") return ObjectClass::kCar;
  if (name == "person") return ObjectClass::kPerson;
  if (name == "bicycle") return ObjectClass::kBicycle;
  throw std::invalid_argument("unknown object class '" + name + "'");
}

InstanceTable::InstanceTable(std::vector<InstanceInfo> instances)
    : instances_(std::move(instances)), index_of_id_(65536, -1) {
  for (size_t i = 0; i < instances_.size(); ++i) {
    const uint16_t id = instances_[i].id;
    if (id == kStaticInstanceId || id == kSkyInstanceId)
      throw std::invalid_argument("instance id " + std::to_string(id) + " is reserved");
    if (index_of_id_[id] >= 0)
      throw std::invalid_argument("duplicate instance id " + std::to_string(id));
    index_of_id_[id] = static_cast<int32_t>(i);
  }
}

const InstanceInfo* InstanceTable::Find(uint16_t id) const {
  if (index_of_id_.empty() || index_of_id_[id] < 0) return nullptr;
  return &instances_[static_cast<size_t>(index_of_id_[id])];
}

bool InstanceTable::IsMoving(uint16_t id) const {
  const InstanceInfo* info = Find(id);
  return info != nullptr && info->moving;
}

std::string InstanceTable::ClassNameOf(uint16_t id) const {
  if (id == kStaticInstanceId) return "background";
  if (id == kSkyInstanceId) return "sky";
  const InstanceInfo* info = Find(id);
  return info ? ClassName(info->object_class) : "unknown";
}

void InstanceTable::Write(std::ostream& out) const {
  out << "# id class moving speed_mps size_x_m size_y_m size_z_m\n"
         "# instance images: 0 = static world, 65535 = sky; object frame: origin on the ground "
         "under the box centre, x right, y down, z forward\n";
  char line[256];
  for (const InstanceInfo& info : instances_) {
    std::snprintf(line, sizeof(line), "%u %s %d %.3f %.3f %.3f %.3f\n",
                  static_cast<unsigned>(info.id), ClassName(info.object_class), info.moving ? 1 : 0,
                  info.speed_mps, info.size_m.x(), info.size_m.y(), info.size_m.z());
    out << line;
  }
}

InstanceTable InstanceTable::Read(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open instance table");
  std::vector<InstanceInfo> instances;
  std::string text;
  int line_no = 0;
  while (std::getline(in, text)) {
    ++line_no;
    if (!text.empty() && text.back() == '\r') text.pop_back();
    const size_t first = text.find_first_not_of(" \t");
    if (first == std::string::npos || text[first] == '#') continue;
    std::istringstream fields(text);
    long long id = -1;
    std::string class_name;
    int moving = -1;
    InstanceInfo info;
    std::string extra;
    if (!(fields >> id >> class_name >> moving >> info.speed_mps >> info.size_m.x() >>
          info.size_m.y() >> info.size_m.z()) ||
        (fields >> extra))
      throw InputError(path, line_no, "expected 'id class moving speed_mps size_x size_y size_z'");
    if (id <= 0 || id >= kSkyInstanceId)
      throw InputError(path, line_no, "instance id must be in [1, 65534]");
    if (moving != 0 && moving != 1) throw InputError(path, line_no, "moving must be 0 or 1");
    try {
      info.object_class = ParseClassName(class_name);
    } catch (const std::invalid_argument& e) {
      throw InputError(path, line_no, e.what());
    }
    info.id = static_cast<uint16_t>(id);
    info.moving = moving == 1;
    for (const InstanceInfo& other : instances)
      if (other.id == info.id)
        throw InputError(path, line_no, "duplicate instance id " + std::to_string(id));
    instances.push_back(info);
  }
  return InstanceTable(std::move(instances));
}

cv::Mat MovingMask(const cv::Mat& instance_image, const InstanceTable& table) {
  if (instance_image.type() != CV_16UC1)
    throw std::invalid_argument("MovingMask: instance image must be CV_16UC1");
  std::vector<uint8_t> moving(65536, 0);
  for (const InstanceInfo& info : table.all())
    if (info.moving) moving[info.id] = 255;
  cv::Mat mask(instance_image.size(), CV_8UC1);
  for (int y = 0; y < instance_image.rows; ++y) {
    const uint16_t* in = instance_image.ptr<uint16_t>(y);
    uint8_t* out = mask.ptr<uint8_t>(y);
    for (int x = 0; x < instance_image.cols; ++x) out[x] = moving[in[x]];
  }
  return mask;
}

}  // namespace pcr::sim
