#include "io/kitti_raw.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <stdexcept>

#include "io/kitti_calib.h"
#include "io/text_parse.h"
#include "slam/common/error.h"

namespace pcr {
namespace {

namespace fs = std::filesystem;

constexpr double kEarthRadiusM = 6378137.0;
constexpr double kDegToRad = std::numbers::pi / 180.0;

// Splits "a<sep>b<sep>c" into exactly n integers, else InputError.
std::vector<int64_t> SplitInts(std::string_view text, char sep, size_t n, const std::string& name,
                               int line, const char* what) {
  std::vector<int64_t> values;
  size_t begin = 0;
  while (true) {
    const size_t end = text.find(sep, begin);
    const std::string_view part = text.substr(begin, end - begin);
    if (part.empty() || part.find_first_not_of("0123456789") != std::string_view::npos)
      throw InputError(name, line, std::string("malformed ") + what);
    values.push_back(io::ParseInt(part, name, line));
    if (end == std::string_view::npos) break;
    begin = end + 1;
  }
  if (values.size() != n) throw InputError(name, line, std::string("malformed ") + what);
  return values;
}

int64_t ParseDateTimeNs(std::string_view date, std::string_view time, const std::string& name,
                        int line) {
  const std::vector<int64_t> ymd = SplitInts(date, '-', 3, name, line, "date (want YYYY-MM-DD)");
  // Ranges checked before the casts, which would wrap a month or day of 2^32 + 9 to 9.
  if (ymd[0] < 1970 || ymd[0] > 2200 || ymd[1] < 1 || ymd[1] > 12 || ymd[2] < 1 || ymd[2] > 31)
    throw InputError(name, line, "invalid date");
  const std::chrono::year_month_day day{std::chrono::year(static_cast<int>(ymd[0])),
                                        std::chrono::month(static_cast<unsigned>(ymd[1])),
                                        std::chrono::day(static_cast<unsigned>(ymd[2]))};
  if (!day.ok()) throw InputError(name, line, "invalid date");
  const size_t first_colon = time.find(':');
  const size_t second_colon =
      first_colon == std::string_view::npos ? first_colon : time.find(':', first_colon + 1);
  if (second_colon == std::string_view::npos)
    throw InputError(name, line, "malformed time (want HH:MM:SS.fraction)");
  const std::vector<int64_t> hm =
      SplitInts(time.substr(0, second_colon), ':', 2, name, line, "time (want HH:MM:SS.fraction)");
  const std::string_view seconds = time.substr(second_colon + 1);
  if (seconds.empty() || seconds.front() == '-' || seconds.front() == '+' ||
      seconds.find_first_of("eE") != std::string_view::npos)
    throw InputError(name, line, "malformed seconds");
  const int64_t seconds_ns = io::ParseSecondsToNs(seconds, name, line);
  if (hm[0] > 23 || hm[1] > 59 || seconds_ns >= 61'000'000'000)
    throw InputError(name, line, "time of day out of range");
  const int64_t days = std::chrono::sys_days(day).time_since_epoch().count();
  return ((days * 24 + hm[0]) * 60 + hm[1]) * 60 * 1'000'000'000 + seconds_ns;
}

SE3 MakePose(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation) {
  SE3 pose = SE3::Identity();
  pose.linear() = rotation;
  pose.translation() = translation;
  return pose;
}

// The times of the frames `numbers` (line k + 1 for frame k) of a timestamps.txt, else
// InputError naming it and the first frame without a line (`images` are the frames' files).
std::vector<int64_t> ReadTimestampsFor(const fs::path& path, const std::vector<int64_t>& numbers,
                                       const std::vector<std::string>& images) {
  const std::vector<int64_t> times = ReadRawTimestamps(path.string());
  RequireLines(times.size(), numbers, images, path.string(), "timestamps",
               std::to_string(numbers.size()) + " images");
  std::vector<int64_t> t_ns;
  for (const int64_t number : numbers) t_ns.push_back(times[number]);
  return t_ns;
}

}  // namespace

OxtsPacket ParseOxtsPacket(std::istream& in, const std::string& name) {
  io::LineReader reader(in, name);
  std::string line;
  std::vector<double> v;
  int data_line = 0;
  while (reader.Next(&line)) {
    if (io::IsBlank(line)) continue;
    if (data_line != 0) throw InputError(name, reader.line_no(), "more than one OXTS record");
    data_line = reader.line_no();
    v = io::ParseExactly(line, 30, name, data_line);
  }
  if (data_line == 0) throw InputError(name, 0, "empty OXTS file");
  OxtsPacket packet;
  packet.lat_deg = v[0];
  packet.lon_deg = v[1];
  packet.alt_m = v[2];
  packet.roll_rad = v[3];
  packet.pitch_rad = v[4];
  packet.yaw_rad = v[5];
  packet.north_mps = v[6];
  packet.east_mps = v[7];
  packet.forward_speed_mps = v[8];
  packet.up_mps = v[10];
  packet.pos_accuracy_m = v[23];
  packet.vel_accuracy_mps = v[24];
  if (std::abs(packet.lat_deg) >= 89.0 || std::abs(packet.lon_deg) > 180.0)
    throw InputError(name, data_line, "latitude/longitude out of range");
  return packet;
}

OxtsPacket ReadOxtsPacket(const std::string& path) {
  std::ifstream in = io::OpenInputFile(path);
  return ParseOxtsPacket(in, path);
}

std::vector<int64_t> ReadRawTimestamps(std::istream& in, const std::string& name) {
  std::vector<int64_t> times_ns;
  io::LineReader reader(in, name);
  std::string line;
  int first_blank_line = 0;
  while (reader.Next(&line)) {
    if (io::IsBlank(line)) {
      if (first_blank_line == 0) first_blank_line = reader.line_no();
      continue;
    }
    if (first_blank_line != 0)
      throw InputError(name, first_blank_line, "blank line before the end of the file");
    const std::vector<std::string_view> tokens = io::SplitWhitespace(line);
    if (tokens.size() != 2)
      throw InputError(name, reader.line_no(),
                       "expected 'YYYY-MM-DD HH:MM:SS.fraction', found " +
                           std::to_string(tokens.size()) + " fields");
    const int64_t t_ns = ParseDateTimeNs(tokens[0], tokens[1], name, reader.line_no());
    if (!times_ns.empty() && t_ns <= times_ns.back())
      throw InputError(name, reader.line_no(), "timestamps must increase strictly");
    times_ns.push_back(t_ns);
  }
  return times_ns;
}

std::vector<int64_t> ReadRawTimestamps(const std::string& path) {
  std::ifstream in = io::OpenInputFile(path);
  return ReadRawTimestamps(in, path);
}

SE3 WorldFromImu(const OxtsPacket& packet, double mercator_scale) {
  const double x_m = mercator_scale * kEarthRadiusM * packet.lon_deg * kDegToRad;
  const double y_m = mercator_scale * kEarthRadiusM *
                     std::log(std::tan((90.0 + packet.lat_deg) * std::numbers::pi / 360.0));
  const Eigen::Matrix3d rotation = (Eigen::AngleAxisd(packet.yaw_rad, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(packet.pitch_rad, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(packet.roll_rad, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  return MakePose(rotation, Eigen::Vector3d(x_m, y_m, packet.alt_m));
}

SE3 ReadCam0FromImu(const std::string& calib_dir) {
  const fs::path dir(calib_dir);
  const CalibFile cam_to_cam = CalibFile::Read((dir / "calib_cam_to_cam.txt").string());
  const CalibFile velo_to_cam = CalibFile::Read((dir / "calib_velo_to_cam.txt").string());
  const CalibFile imu_to_velo = CalibFile::Read((dir / "calib_imu_to_velo.txt").string());
  const SE3 rect0_from_cam0 = MakePose(cam_to_cam.Rotation("R_rect_00"), Eigen::Vector3d::Zero());
  const SE3 cam0_from_velo = MakePose(velo_to_cam.Rotation("R"), velo_to_cam.Vector3("T"));
  const SE3 velo_from_imu = MakePose(imu_to_velo.Rotation("R"), imu_to_velo.Vector3("T"));
  return rect0_from_cam0 * cam0_from_velo * velo_from_imu;
}

Trajectory OxtsToCam0Trajectory(const std::vector<OxtsPacket>& packets, const SE3& cam0_from_imu,
                                const std::vector<int64_t>& t_ns, RawTruth truth,
                                const std::vector<int64_t>& packet_t_ns) {
  Trajectory trajectory;
  if (packets.empty()) return trajectory;
  const std::vector<int64_t>& times = packet_t_ns.empty() ? t_ns : packet_t_ns;
  if (truth == RawTruth::kIns && times.size() < packets.size())
    throw std::invalid_argument("OxtsToCam0Trajectory: " + std::to_string(times.size()) +
                                " times for " + std::to_string(packets.size()) + " packets");
  const double mercator_scale = std::cos(packets.front().lat_deg * kDegToRad);
  const SE3 imu_from_cam0 = cam0_from_imu.inverse();
  // Positions are taken relative to the first packet's before composing, so that frame 0 is
  // exactly the identity and no precision is lost to Mercator coordinates of ~1e6 m.
  const Eigen::Vector3d origin_m = WorldFromImu(packets.front(), mercator_scale).translation();
  Eigen::Vector3d integrated_m = Eigen::Vector3d::Zero();  // kIns: east, north, up from packet 0
  const auto velocity = [](const OxtsPacket& p) {
    return Eigen::Vector3d(p.east_mps, p.north_mps, p.up_mps);
  };
  std::vector<SE3> local_world_from_cam0;
  for (size_t i = 0; i < packets.size(); ++i) {
    SE3 world_from_imu = WorldFromImu(packets[i], mercator_scale);
    if (truth == RawTruth::kGps) {
      world_from_imu.translation() -= origin_m;
    } else {
      if (i > 0) {
        if (times[i] <= times[i - 1])
          throw std::invalid_argument("OxtsToCam0Trajectory: packet times must increase");
        integrated_m += 0.5 * (velocity(packets[i - 1]) + velocity(packets[i])) *
                        NsToSeconds(times[i] - times[i - 1]);
      }
      world_from_imu.translation() = integrated_m;
      if (i < t_ns.size())  // at the image's time (nothing when the times are the same)
        world_from_imu.translation() += velocity(packets[i]) * NsToSeconds(t_ns[i] - times[i]);
    }
    local_world_from_cam0.push_back(world_from_imu * imu_from_cam0);
  }
  const SE3 origin_from_world = local_world_from_cam0.front().inverse();
  for (size_t i = 0; i < packets.size(); ++i) {
    StampedPose pose;
    pose.t_ns = i < t_ns.size() ? t_ns[i] : 0;
    pose.frame_index = static_cast<int64_t>(i);
    pose.world_from_cam = i == 0 ? SE3::Identity() : origin_from_world * local_world_from_cam0[i];
    trajectory.push_back(pose);
  }
  return trajectory;
}

std::vector<OxtsPacket> ReadOxtsPackets(const std::string& drive_dir,
                                        const std::vector<int64_t>& frame_numbers) {
  const fs::path oxts_dir = fs::path(drive_dir) / "oxts" / "data";
  std::error_code ec;
  if (!fs::is_directory(oxts_dir, ec)) return {};
  std::vector<int64_t> numbers;
  const std::vector<std::string> paths = ListFrameFiles(oxts_dir.string(), ".txt", &numbers);
  std::vector<OxtsPacket> packets;
  for (const int64_t frame : frame_numbers) {
    const auto at = std::lower_bound(numbers.begin(), numbers.end(), frame);
    if (at == numbers.end() || *at != frame)
      throw InputError(oxts_dir.string(), 0,
                       std::to_string(paths.size()) + " OXTS records but " +
                           std::to_string(frame_numbers.size()) + " images: none for frame " +
                           std::to_string(frame));
    packets.push_back(ReadOxtsPacket(paths[static_cast<size_t>(at - numbers.begin())]));
  }
  return packets;
}

Dataset OpenKittiRaw(const std::string& drive_dir, KittiCameras cams, RawTruth truth) {
  std::error_code ec;
  if (!fs::is_directory(drive_dir, ec))
    throw InputError(drive_dir, 0,
                     fs::exists(drive_dir, ec) ? "not a directory (a drive is a directory)"
                                               : "drive directory not found");
  const fs::path dir = NormalDirectoryPath(drive_dir);
  // The date folder's calibration (of the link's target where the drive is a link).
  const fs::path calib_dir =
      fs::path(FirstDirectoryWhere(dir.string(), [](const std::string& d) {
        std::error_code e;
        return fs::is_regular_file(fs::path(d).parent_path() / "calib_cam_to_cam.txt", e);
      })).parent_path();

  Dataset dataset;
  dataset.root = dir.string();
  dataset.name = dir.filename().string();

  const bool color = cams == KittiCameras::kColor;
  const std::string left_name = color ? "image_02" : "image_00";
  const std::string right_name = color ? "image_03" : "image_01";
  const fs::path left_dir = dir / left_name;
  if (!fs::is_directory(left_dir / "data", ec))
    throw InputError((left_dir / "data").string(), 0, "image directory not found");
  std::vector<int64_t> numbers;
  dataset.left_paths = ListFrameFiles((left_dir / "data").string(), ".png", &numbers);
  if (dataset.left_paths.empty())
    throw InputError((left_dir / "data").string(), 0, "no PNG images");
  AddOtherCameras(&dataset, numbers, left_name + "/data", (dir / right_name / "data").string(),
                  (dir / "image_02" / "data").string(), color);

  dataset.t_ns = ReadTimestampsFor(left_dir / "timestamps.txt", numbers, dataset.left_paths);
  dataset.frame_numbers = numbers;

  const CalibFile cam_to_cam = CalibFile::Read((calib_dir / "calib_cam_to_cam.txt").string());
  SetRigFromCalib(cam_to_cam, color ? "P_rect_02" : "P_rect_00", color ? "P_rect_03" : "P_rect_01",
                  &dataset);

  const std::vector<OxtsPacket> packets = ReadOxtsPackets(dir.string(), numbers);
  if (!packets.empty()) {
    std::vector<int64_t> packet_t_ns;
    std::string times_note = "oxts/timestamps.txt";
    const fs::path oxts_times = dir / "oxts" / "timestamps.txt";
    if (truth == RawTruth::kIns && fs::exists(oxts_times, ec)) {
      packet_t_ns = ReadTimestampsFor(oxts_times, numbers, dataset.left_paths);
    } else if (truth == RawTruth::kIns) {
      times_note = "the image times";
    }
    dataset.ground_truth = OxtsToCam0Trajectory(packets, ReadCam0FromImu(calib_dir.string()),
                                                dataset.t_ns, truth, packet_t_ns);
    dataset.ground_truth_source =
        (dir / "oxts" / "data").string() +
        (truth == RawTruth::kIns
             ? " (positions: OXTS velocities integrated over " + times_note + ")"
             : std::string(" (positions: OXTS GPS latitude/longitude/altitude)"));
  }
  return dataset;
}

}  // namespace pcr
