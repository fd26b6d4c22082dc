#pragma once
// A recorded image sequence (KITTI odometry sequence or raw drive) as plain data: calibration,
// timestamps, image paths and optional ground truth. Images are read lazily and checked, so a
// truncated or unreadable file throws pcr::InputError naming it.
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

#include "io/kitti_calib.h"
#include "slam/common/camera.h"
#include "slam/common/pose.h"

namespace pcr {

// Which KITTI camera pair to read: cameras 0/1 (grey) or 2/3 (colour).
enum class KittiCameras { kGray, kColor };

// Where a raw drive's ground-truth positions come from; orientations are always the OXTS roll,
// pitch and yaw. kIns: integrated from the OXTS north/east/up velocities (the GPS/INS's fused
// velocity, vel_accuracy 0.03-0.07 m/s on drive 0005): locally consistent, drifting slowly.
// kGps: the OXTS latitude, longitude and altitude, as the KITTI devkit's poses (pos_accuracy
// 0.3-0.5 m on drive 0005): no drift, but a short clip sees that error as a trajectory error (on
// drive 0005 the positions' path is 33.6 m, 4% shorter than the velocities' 34.9 m).
enum class RawTruth { kIns, kGps };
const char* ToString(RawTruth truth);  // "ins", "gps"
// "ins" or "gps"; throws std::invalid_argument for anything else.
RawTruth ParseRawTruth(const std::string& text);

struct Dataset {
  std::string name;  // "06", "2011_09_26_drive_0005_sync"
  std::string root;  // the directory that was opened, absolute and lexically normal
  StereoRig rig;     // rectified left camera; baseline_m = 0 when there is no right image stream
  std::vector<int64_t> t_ns;  // per frame, strictly increasing
  // per frame, the number in its image's name (000042.png: 42), strictly increasing; the line of
  // times.txt, the poses and the OXTS record it was paired with
  std::vector<int64_t> frame_numbers;
  // world_from_cam0 (rectified camera 0) per frame, t_ns and frame_index set; frame 0 is the
  // identity for raw drives (OXTS), as in the KITTI odometry pose files.
  std::optional<Trajectory> ground_truth;
  // poses/NN.txt, or the OXTS folder and what the positions came from; empty without ground truth
  std::string ground_truth_source;
  std::vector<std::string> left_paths;
  std::vector<std::string> right_paths;  // empty for a monocular sequence
  // Why a folder of right images is not used (the calibration lacks their camera), else empty.
  std::string right_unused;
  std::vector<std::string> left_color_paths;  // camera 2 colour images when present, else empty

  size_t size() const { return left_paths.size(); }
  // Frame i's image number (frame_numbers[i]; i itself where frame_numbers is empty, as in a
  // dataset built by hand). Throws std::out_of_range for a bad index.
  int64_t FrameNumber(size_t i) const {
    return frame_numbers.empty() ? static_cast<int64_t>(i) : frame_numbers.at(i);
  }
  bool has_right() const { return !right_paths.empty(); }
  bool has_color() const { return !left_color_paths.empty(); }
  double DurationSeconds() const {
    return t_ns.size() < 2 ? 0.0 : NsToSeconds(t_ns.back() - t_ns.front());
  }

  // CV_8UC1; colour files are converted to grey. Throws InputError for an unreadable file, or an
  // image whose size is not the rig's (rig.left.width_px x height_px, when set), and
  // std::out_of_range for a bad index.
  cv::Mat LoadLeft(size_t i) const;
  cv::Mat LoadRight(size_t i) const;
  // CV_8UC3 BGR from left_color_paths (camera 2, which sits about 6 cm from camera 0).
  cv::Mat LoadLeftColor(size_t i) const;
};

// Reads and decodes an image file. PNG files must carry the PNG signature and end with an IEND
// chunk (OpenCV silently decodes truncated PNGs). flags as for cv::imdecode.
cv::Mat LoadImageChecked(const std::string& path, int flags);

// Reads an image as CV_8UC1: grey files as they are, colour files through cv::cvtColor.
cv::Mat LoadGreyImage(const std::string& path);

// Width and height of a PNG from its IHDR chunk (other formats are decoded).
cv::Size ImageSizeOf(const std::string& path);

// Fills dataset->rig from the rectified 3x4 projection matrices `left_key` of `calib` and, when
// the dataset has a right image stream, `right_key` (baseline = (P_left[0][3] - P_right[0][3]) /
// fx; without a right stream the entry is not needed), and the dataset's image size (see
// DatasetImageSize). Throws InputError naming the calibration file and the entry's line for a
// missing entry, a focal length that is not positive, a principal point outside the image, a
// right camera whose fx, fy, cx or cy differ from the left one's (rectified stereo shares one
// camera), or a baseline that is not positive.
void SetRigFromCalib(const CalibFile& calib, const std::string& left_key,
                     const std::string& right_key, Dataset* dataset);

// The size of a camera's images (`paths`, one camera, in frame order) without decoding them: the
// size in the headers of the first, middle and last image that at least two of them share, so one
// odd frame, the first included, does not set it (Dataset::Load* then rejects that frame). Throws
// InputError naming the first image when the sampled images disagree with no majority.
cv::Size DatasetImageSize(const std::vector<std::string>& paths);

// Sorted paths of the files in `dir` whose names end with `extension` (e.g. ".png"), in any case
// (".PNG" too).
std::vector<std::string> ListFiles(const std::string& dir, const std::string& extension);

// `dir` made absolute and lexically normal, without a trailing separator or "." ("07", "./07/.",
// "seq/07/" -> "<cwd>/.../07"), so that its file name and parents are those of the directory.
std::string NormalDirectoryPath(const std::string& dir);

// Whether dir has a KITTI raw drive's layout (image_00/data or image_02/data), which OpenDataset
// opens as one.
bool IsKittiRawDrive(const std::string& dir);

// Where the files beside a dataset directory (the poses two levels up, a raw drive's calibration
// one level up) are looked for: `normal_dir` as given, then, when it is or passes through a
// symbolic link, the directory it resolves to. Returns the first of these for which `holds`
// (called with the candidate directory) is true, else `normal_dir`.
std::string FirstDirectoryWhere(const std::string& normal_dir,
                                const std::function<bool(const std::string&)>& holds);

// The files of `dir` ending with `extension` whose names are frame numbers ("000042.png": 42),
// sorted by number; *numbers gets the numbers. Throws InputError naming a file whose name before
// the extension is not a decimal number, or the second of two files of one number.
std::vector<std::string> ListFrameFiles(const std::string& dir, const std::string& extension,
                                        std::vector<int64_t>* numbers);

// Throws InputError(file, 0, "N <what> but <of>: none for frame K (<image name>)") when a frame
// number has no line among the file's `lines` (`images` are the frames' files, `numbers` theirs).
void RequireLines(size_t lines, const std::vector<int64_t>& numbers,
                  const std::vector<std::string>& images, const std::string& file,
                  const std::string& what, const std::string& of);

// Throws InputError naming `other_dir` unless `other` holds exactly the file names of `left`
// (paired frames of two cameras), naming the first file that is not in both.
void CheckSameFileNames(const std::vector<std::string>& left, const std::string& left_dir,
                        const std::vector<std::string>& other, const std::string& other_dir);

// Sets dataset->right_paths and left_color_paths for the left images (left_paths, whose frame
// numbers are `numbers`, in folder `left_label`): the images of `right_dir`, none when it does
// not exist (else one of each left image's name, or InputError naming right_dir); the left
// images themselves when `color`, else the images of `colour_dir` when it holds exactly the left
// images' frames (none otherwise, with a warning that names the folder and the frames that differ).
void AddOtherCameras(Dataset* dataset, const std::vector<int64_t>& numbers,
                     const std::string& left_label, const std::string& right_dir,
                     const std::string& colour_dir, bool color);

// Opens a KITTI odometry sequence directory or a KITTI raw drive directory, decided by the
// layout (calib.txt + image_0/image_2 vs image_00/data). raw_truth: a raw drive's ground truth.
Dataset OpenDataset(const std::string& path, KittiCameras cams = KittiCameras::kGray,
                    RawTruth raw_truth = RawTruth::kIns);

}  // namespace pcr
