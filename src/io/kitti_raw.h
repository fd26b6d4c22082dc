#pragma once
// KITTI raw drive: DATE/DATE_drive_NNNN_sync/{image_00..image_03/data/*.png + timestamps.txt,
// oxts/data/*.txt} with calib_cam_to_cam.txt, calib_velo_to_cam.txt and calib_imu_to_velo.txt in
// DATE/. Ground truth comes from OXTS (GPS/INS) expressed in the rectified camera 0 frame.
#include <cstdint>
#include <istream>
#include <string>
#include <vector>

#include "io/dataset.h"

namespace pcr {

// One OXTS record (oxts/data/%010d.txt: 30 numbers on one line; see oxts/dataformat.txt).
struct OxtsPacket {
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  double roll_rad = 0, pitch_rad = 0, yaw_rad = 0;  // yaw 0 = east, counter-clockwise positive
  double north_mps = 0, east_mps = 0;               // vn, ve: columns 7 and 8 of the record
  double forward_speed_mps = 0;                     // vf, column 9
  double up_mps = 0;                                // vu, column 11
  double pos_accuracy_m = 0;                        // column 24 (north/east)
  double vel_accuracy_mps = 0;                      // column 25 (north/east)
};

OxtsPacket ReadOxtsPacket(const std::string& path);
OxtsPacket ParseOxtsPacket(std::istream& in, const std::string& name);

// "2011-09-26 13:04:32.351950336" lines -> nanoseconds since the Unix epoch (the clock is taken
// as UTC). Times must increase strictly.
std::vector<int64_t> ReadRawTimestamps(const std::string& path);
std::vector<int64_t> ReadRawTimestamps(std::istream& in, const std::string& name);

// world_from_imu for one packet in a local Mercator frame (x east, y north, z up; earth radius
// 6378137 m; mercator_scale = cos(latitude of the first packet)), R = Rz(yaw) Ry(pitch) Rx(roll).
SE3 WorldFromImu(const OxtsPacket& packet, double mercator_scale);

// Rectified camera 0 from IMU: R_rect_00 * cam0_from_velo * velo_from_imu, from the three calib
// files in calib_dir.
SE3 ReadCam0FromImu(const std::string& calib_dir);

// world_from_cam0 per packet relative to the first (pose 0 = identity):
// inv(W_0) * W_i with W_i = world_from_imu_i * inv(cam0_from_imu). world_from_imu_i has the
// rotation of WorldFromImu(p_i) and, for kGps, its translation; for kIns, the integral of the
// packets' east/north/up velocities (trapezoid rule over packet_t_ns) from the first packet's
// translation, carried by packet i's velocity from packet_t_ns[i] to t_ns[i] (the image's time:
// on drive 0005 the two differ by up to 5 ms, 2 cm at its speed). t_ns[i] and frame_index = i
// are set (t_ns may be empty: times 0). packet_t_ns: the packets' times (kIns; empty: t_ns);
// throws std::invalid_argument when kIns has fewer times than packets or times that do not
// increase.
Trajectory OxtsToCam0Trajectory(const std::vector<OxtsPacket>& packets, const SE3& cam0_from_imu,
                                const std::vector<int64_t>& t_ns, RawTruth truth = RawTruth::kGps,
                                const std::vector<int64_t>& packet_t_ns = {});

// The OXTS records of the frames `frame_numbers` of a raw drive (frame k: the file of number k in
// DRIVE/oxts/data, e.g. 0000000042.txt); empty without an oxts/data folder. Throws InputError
// naming the folder and the frame when a frame has no record, the file of a bad record, or a file
// whose name is not a frame number.
std::vector<OxtsPacket> ReadOxtsPackets(const std::string& drive_dir,
                                        const std::vector<int64_t>& frame_numbers);

// Rig from P_rect_00/P_rect_01 (kGray) or P_rect_02/P_rect_03 (kColor), baseline
// (P_left[0][3] - P_right[0][3]) / fx. Frames are paired by the number in the image names, not by
// position: image 0000000042.png takes line 43 of the timestamps files and oxts/data/0000000042.txt
// (a clip that starts after frame 0, or has a gap, gets its own lines; lines and records without
// an image are not used), and the right (and colour) images must carry the left images' names.
// Ground truth from oxts/data when present (OXTS files must then cover every frame) by `truth`;
// kIns integrates over oxts/timestamps.txt (the image timestamps when it is missing); its
// frame_index is the position in the dataset. image_02 fills left_color_paths when it holds the
// left images' names. drive_dir may be relative or end with '/' or "/.": the calibration is read
// from the parent of the directory itself. Throws InputError naming the file and the frame when
// an image has no timestamp or OXTS record, or an image name is not a number.
Dataset OpenKittiRaw(const std::string& drive_dir, KittiCameras cams = KittiCameras::kGray,
                     RawTruth truth = RawTruth::kIns);

}  // namespace pcr
