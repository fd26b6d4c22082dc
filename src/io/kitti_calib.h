#pragma once
// KITTI calibration files: one "KEY: values" entry per line (odometry calib.txt and the raw
// calib_cam_to_cam.txt, calib_velo_to_cam.txt, calib_imu_to_velo.txt). Values are parsed when
// asked for, so text entries such as "calib_time: 09-Jan-2012 13:57:47" are kept but never read
// as numbers. Errors throw pcr::InputError naming the file and the entry's 1-based line.
#include <Eigen/Core>
#include <istream>
#include <map>
#include <string>
#include <vector>

namespace pcr {

class CalibFile {
 public:
  // Missing file, a non-blank line without "KEY:", a key with bytes that are not printable ASCII
  // (a control byte; a UTF-8 byte order mark before the first line is read past, io::LineReader)
  // or a repeated key throw InputError.
  static CalibFile Read(const std::string& path);
  static CalibFile Parse(std::istream& in, const std::string& name);

  bool Has(const std::string& key) const { return entries_.count(key) != 0; }
  const std::string& name() const { return name_; }
  // The 1-based line of `key`; 0 when it is missing.
  int Line(const std::string& key) const;
  // Exactly `count` finite numbers of `key`; throws when the key is missing or malformed.
  std::vector<double> Numbers(const std::string& key, size_t count) const;
  Eigen::Matrix<double, 3, 4> Matrix3x4(const std::string& key) const;  // row-major
  Eigen::Matrix3d Matrix3(const std::string& key) const;                // row-major
  Eigen::Vector3d Vector3(const std::string& key) const;
  // The entry's rotation (row-major 3x3), projected onto SO(3).
  Eigen::Matrix3d Rotation(const std::string& key) const;

 private:
  struct Entry {
    std::string value;
    int line = 0;
  };
  std::string name_;
  std::map<std::string, Entry> entries_;
};

}  // namespace pcr
