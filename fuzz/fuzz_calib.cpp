// libFuzzer target: KITTI calibration files (odometry calib.txt and raw calib_*.txt) and the
// matrix accessors used by the dataset readers.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "io/kitti_calib.h"
#include "slam/common/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    std::istringstream in(text);
    const pcr::CalibFile calib = pcr::CalibFile::Parse(in, "fuzz.calib");
    for (const char* key : {"P0", "P1", "P_rect_00", "P_rect_01"}) {
      try {
        (void)calib.Matrix3x4(key);
      } catch (const pcr::InputError&) {
      }
    }
    for (const char* key : {"R", "R_rect_00"}) {
      try {
        (void)calib.Rotation(key);
      } catch (const pcr::InputError&) {
      }
    }
    try {
      (void)calib.Vector3("T");
    } catch (const pcr::InputError&) {
    }
  } catch (const pcr::InputError&) {
  }
  return 0;
}
