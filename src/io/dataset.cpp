#include "io/dataset.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <stdexcept>

#include "io/kitti_odometry.h"
#include "io/kitti_raw.h"
#include "slam/common/error.h"
#include "slam/common/image.h"
#include "slam/common/log.h"

namespace pcr {
namespace {

namespace fs = std::filesystem;

constexpr std::array<unsigned char, 8> kPngSignature = {0x89, 'P',  'N',  'G',
                                                        '\r', '\n', 0x1a, '\n'};
// The last 12 bytes of every complete PNG: zero length, "IEND", CRC.
constexpr std::array<unsigned char, 12> kPngIend = {0,   0,   0,    0,    'I',  'E',
                                                    'N', 'D', 0xae, 0x42, 0x60, 0x82};

std::string Lowercase(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

bool HasPngExtension(const std::string& path) {
  return Lowercase(fs::path(path).extension().string()) == ".png";
}

// `image`, loaded from `path`, when its size is the rig's (or the rig has none).
cv::Mat RequireRigSize(cv::Mat image, const std::string& path, const PinholeCamera& camera) {
  const cv::Size expected(camera.width_px, camera.height_px);
  if (expected.width > 0 && expected.height > 0 && image.size() != expected)
    throw InputError(path, 0,
                     "image is " + SizeText(image.size()) + ", but the dataset's images are " +
                         SizeText(expected));
  return image;
}

std::string FileName(const std::string& path) { return fs::path(path).filename().string(); }

// Up to `shown` of `numbers`, comma-separated, then "and N more".
std::string NumberList(const std::vector<int64_t>& numbers, size_t shown = 5) {
  std::string out;
  for (size_t i = 0; i < numbers.size() && i < shown; ++i)
    out += (i ? ", " : "") + std::to_string(numbers[i]);
  if (numbers.size() > shown) out += " and " + std::to_string(numbers.size() - shown) + " more";
  return out;
}

std::vector<unsigned char> ReadBytes(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path, 0, "image file not found");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open image file");
  std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, 0, "read error");
  return bytes;
}

void CheckPng(const std::string& path, const std::vector<unsigned char>& bytes) {
  if (bytes.size() < kPngSignature.size() + kPngIend.size() ||
      !std::equal(kPngSignature.begin(), kPngSignature.end(), bytes.begin()))
    throw InputError(path, 0, "not a PNG file (bad signature)");
  if (!std::equal(kPngIend.begin(), kPngIend.end(), bytes.end() - kPngIend.size()))
    throw InputError(path, 0, "truncated PNG (no IEND chunk at the end)");
}

const std::string& PathAt(const std::vector<std::string>& paths, size_t i, const char* what) {
  if (i >= paths.size())
    throw std::out_of_range(std::string(what) + " image index " + std::to_string(i) +
                            " out of range (" + std::to_string(paths.size()) + " images)");
  return paths[i];
}

}  // namespace

cv::Mat LoadImageChecked(const std::string& path, int flags) {
  const std::vector<unsigned char> bytes = ReadBytes(path);
  if (HasPngExtension(path)) CheckPng(path, bytes);
  cv::Mat image;
  try {
    image = cv::imdecode(bytes, flags);
  } catch (const cv::Exception& e) {
    throw InputError(path, 0, std::string("cannot decode image: ") + e.what());
  }
  if (image.empty()) throw InputError(path, 0, "cannot decode image");
  return image;
}

cv::Size ImageSizeOf(const std::string& path) {
  if (HasPngExtension(path)) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, 0, "image file not found");
    std::array<unsigned char, 24> header{};
    in.read(reinterpret_cast<char*>(header.data()), header.size());
    const bool ihdr = in.gcount() == 24 &&
                      std::equal(kPngSignature.begin(), kPngSignature.end(), header.begin()) &&
                      header[12] == 'I' && header[13] == 'H' && header[14] == 'D' &&
                      header[15] == 'R';
    if (!ihdr) throw InputError(path, 0, "not a PNG file (no IHDR header)");
    const auto be32 = [&](int at) {
      return (static_cast<uint32_t>(header[at]) << 24) |
             (static_cast<uint32_t>(header[at + 1]) << 16) |
             (static_cast<uint32_t>(header[at + 2]) << 8) | static_cast<uint32_t>(header[at + 3]);
    };
    const uint32_t width = be32(16), height = be32(20);
    if (width == 0 || height == 0 || width > (1u << 20) || height > (1u << 20))
      throw InputError(path, 0, "PNG header gives an invalid image size");
    return {static_cast<int>(width), static_cast<int>(height)};
  }
  return LoadImageChecked(path, cv::IMREAD_UNCHANGED).size();
}

std::vector<std::string> ListFiles(const std::string& dir, const std::string& extension) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError(dir, 0, "directory not found");
  std::vector<std::string> paths;
  const std::string suffix = Lowercase(extension);
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    const std::string name = Lowercase(entry.path().filename().string());
    if (name.size() > suffix.size() &&
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
      paths.push_back(entry.path().string());
  }
  std::sort(paths.begin(), paths.end());
  return paths;
}

std::string NormalDirectoryPath(const std::string& dir) {
  std::error_code ec;
  fs::path path = fs::absolute(fs::path(dir), ec);
  if (ec) path = fs::path(dir);
  path = path.lexically_normal();
  if (path.filename().empty() && path.has_relative_path()) path = path.parent_path();  // "a/b/"
  return path.string();
}

bool IsKittiRawDrive(const std::string& dir) {
  std::error_code ec;
  return fs::is_directory(fs::path(dir) / "image_00" / "data", ec) ||
         fs::is_directory(fs::path(dir) / "image_02" / "data", ec);
}

std::string FirstDirectoryWhere(const std::string& normal_dir,
                                const std::function<bool(const std::string&)>& holds) {
  if (holds(normal_dir)) return normal_dir;
  std::error_code ec;
  const fs::path target = fs::canonical(normal_dir, ec);
  if (!ec && target.string() != normal_dir && holds(target.string())) return target.string();
  return normal_dir;
}

std::vector<std::string> ListFrameFiles(const std::string& dir, const std::string& extension,
                                        std::vector<int64_t>* numbers) {
  std::vector<std::pair<int64_t, std::string>> frames;
  for (std::string& path : ListFiles(dir, extension)) {
    const std::string name = fs::path(path).filename().string();
    const std::string_view stem = std::string_view(name).substr(0, name.size() - extension.size());
    int64_t number = 0;
    const auto [end, ec] = std::from_chars(stem.data(), stem.data() + stem.size(), number);
    if (stem.empty() || stem.front() == '-' || end != stem.data() + stem.size() ||
        ec != std::errc())
      throw InputError(path, 0,
                       "file name is not a frame number (want e.g. 000042" + extension + ")");
    frames.emplace_back(number, std::move(path));
  }
  std::sort(frames.begin(), frames.end());
  numbers->clear();
  std::vector<std::string> paths;
  for (size_t i = 0; i < frames.size(); ++i) {
    if (i > 0 && frames[i].first == frames[i - 1].first)
      throw InputError(frames[i].second, 0,
                       "frame " + std::to_string(frames[i].first) + " is also " +
                           fs::path(paths.back()).filename().string());
    numbers->push_back(frames[i].first);
    paths.push_back(std::move(frames[i].second));
  }
  return paths;
}

void RequireLines(size_t lines, const std::vector<int64_t>& numbers,
                  const std::vector<std::string>& images, const std::string& file,
                  const std::string& what, const std::string& of) {
  for (size_t i = 0; i < numbers.size(); ++i)
    if (static_cast<uint64_t>(numbers[i]) >= lines)
      throw InputError(file, 0,
                       std::to_string(lines) + " " + what + " but " + of + ": none for frame " +
                           std::to_string(numbers[i]) + " (" +
                           fs::path(images[i]).filename().string() + ")");
}

void CheckSameFileNames(const std::vector<std::string>& left, const std::string& left_dir,
                        const std::vector<std::string>& other, const std::string& other_dir) {
  const auto names = [](const std::vector<std::string>& paths) {
    std::vector<std::string> out;
    for (const std::string& path : paths) out.push_back(fs::path(path).filename().string());
    return out;
  };
  const std::vector<std::string> left_names = names(left), other_names = names(other);
  const std::set<std::string> left_set(left_names.begin(), left_names.end());
  const std::set<std::string> other_set(other_names.begin(), other_names.end());
  for (const std::string& name : left_names)
    if (!other_set.count(name))
      throw InputError(other_dir, 0, "no " + name + " to pair with " + left_dir + "/" + name);
  for (const std::string& name : other_names)
    if (!left_set.count(name)) throw InputError(other_dir, 0, name + " has no pair in " + left_dir);
}

void AddOtherCameras(Dataset* dataset, const std::vector<int64_t>& numbers,
                     const std::string& left_label, const std::string& right_dir,
                     const std::string& colour_dir, bool color) {
  // Images missing between the first and the last: the frames are the images there are.
  std::vector<int64_t> gaps;  // the first five missing numbers
  int64_t missing = 0;
  for (size_t i = 1; i < numbers.size(); ++i) {
    missing += numbers[i] - numbers[i - 1] - 1;
    for (int64_t n = numbers[i - 1] + 1; n < numbers[i] && gaps.size() < 5; ++n) gaps.push_back(n);
  }
  if (missing > 0) {
    Logger().warn(
        "{}: {} image{} missing between {} and {} (frame{} {}): the clip's frames are its {} "
        "images, so from the first gap on a frame number of the outputs (and --frames) is not "
        "its image's number; each image keeps its own timestamp and ground truth",
        left_label, missing, missing > 1 ? "s" : "", numbers.front(), numbers.back(),
        missing > 1 ? "s" : "",
        NumberList(gaps) + (missing > 5 ? " and " + std::to_string(missing - 5) + " more" : ""),
        numbers.size());
  }
  std::error_code ec;
  std::vector<int64_t> other_numbers;
  dataset->right_paths.clear();
  if (fs::is_directory(right_dir, ec)) {
    dataset->right_paths = ListFrameFiles(right_dir, ".png", &other_numbers);
    // Names the first image without a pair (so also where the counts differ).
    CheckSameFileNames(dataset->left_paths, left_label, dataset->right_paths, right_dir);
  }
  dataset->left_color_paths.clear();
  if (color) {
    dataset->left_color_paths = dataset->left_paths;
  } else if (fs::is_directory(colour_dir, ec)) {
    // A colour folder that does not hold exactly the left images' frames is not used.
    std::string why;
    try {
      dataset->left_color_paths = ListFrameFiles(colour_dir, ".png", &other_numbers);
      std::vector<int64_t> missing, extra;
      std::set_difference(numbers.begin(), numbers.end(), other_numbers.begin(),
                          other_numbers.end(), std::back_inserter(missing));
      std::set_difference(other_numbers.begin(), other_numbers.end(), numbers.begin(),
                          numbers.end(), std::back_inserter(extra));
      if (!missing.empty())
        why = "no image for frame" + std::string(missing.size() > 1 ? "s " : " ") +
              NumberList(missing) + " of " + left_label;
      if (!extra.empty())
        why += (why.empty() ? "" : "; ") + std::string("frame") + (extra.size() > 1 ? "s " : " ") +
               NumberList(extra) + " not in " + left_label;
    } catch (const InputError& e) {
      why = e.what();
    }
    if (!why.empty()) {
      dataset->left_color_paths.clear();
      Logger().warn("{}: colour images not used (the segmenter gets grey ones): {}", colour_dir,
                    why);
    }
  }
}

cv::Mat LoadGreyImage(const std::string& path) {
  // Decoded as stored, then converted with cvtColor so grey values match
  // cvtColor(LoadLeftColor(i)) (the decoder's own colour-to-grey conversion differs slightly).
  cv::Mat image = LoadImageChecked(path, cv::IMREAD_ANYCOLOR);
  if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, image, cv::COLOR_BGRA2GRAY);
  if (image.type() != CV_8UC1) throw InputError(path, 0, "unsupported pixel format");
  return image;
}

cv::Mat Dataset::LoadLeft(size_t i) const {
  const std::string& path = PathAt(left_paths, i, "left");
  return RequireRigSize(LoadGreyImage(path), path, rig.left);
}

cv::Mat Dataset::LoadRight(size_t i) const {
  const std::string& path = PathAt(right_paths, i, "right");
  return RequireRigSize(LoadGreyImage(path), path, rig.left);
}

cv::Mat Dataset::LoadLeftColor(size_t i) const {
  const std::string& path = PathAt(left_color_paths, i, "colour");
  return RequireRigSize(LoadImageChecked(path, cv::IMREAD_COLOR), path, rig.left);
}

const char* ToString(RawTruth truth) { return truth == RawTruth::kIns ? "ins" : "gps"; }

RawTruth ParseRawTruth(const std::string& text) {
  if (text == "ins") return RawTruth::kIns;
  if (text == "gps") return RawTruth::kGps;
  throw std::invalid_argument("raw truth must be ins or gps, not '" + text + "'");
}

Dataset OpenDataset(const std::string& path, KittiCameras cams, RawTruth raw_truth) {
  std::error_code ec;
  if (!fs::is_directory(path, ec))
    throw InputError(path, 0,
                     fs::exists(path, ec) ? "not a directory (a dataset is a sequence or drive "
                                            "directory)"
                                          : "dataset directory not found");
  const fs::path dir(path);
  if (IsKittiRawDrive(path)) return OpenKittiRaw(path, cams, raw_truth);
  if (fs::exists(dir / "calib.txt", ec)) {
    // Its ground truth is poses/NN.txt: asking for GPS positions would be ignored.
    if (raw_truth == RawTruth::kGps)
      throw InputError(path, 0,
                       "GPS ground truth (--raw-truth gps) needs a KITTI raw drive's OXTS "
                       "records; this is an odometry sequence (its truth is poses/NN.txt)");
    return OpenKittiOdometry(path, cams);
  }
  throw InputError(path, 0,
                   "not a KITTI odometry sequence (calib.txt, image_0/) nor a raw drive "
                   "(image_00/data/)");
}

cv::Size DatasetImageSize(const std::vector<std::string>& paths) {
  if (paths.empty()) throw std::invalid_argument("DatasetImageSize: no images");
  std::vector<size_t> samples = {0, paths.size() / 2, paths.size() - 1};
  samples.erase(std::unique(samples.begin(), samples.end()), samples.end());
  std::vector<cv::Size> sizes;
  for (const size_t i : samples) sizes.push_back(ImageSizeOf(paths[i]));
  for (const cv::Size& size : sizes)
    if (sizes.size() == 1 || std::count(sizes.begin(), sizes.end(), size) >= 2) return size;
  std::string others;
  for (size_t k = 1; k < samples.size(); ++k)
    others += (k > 1 ? " and " : "") + FileName(paths[samples[k]]) + " is " + SizeText(sizes[k]);
  throw InputError(paths.front(), 0,
                   "image is " + SizeText(sizes.front()) + ", but " + others +
                       ": a camera's images must share one size");
}

void SetRigFromCalib(const CalibFile& calib, const std::string& left_key,
                     const std::string& right_key, Dataset* dataset) {
  const Eigen::Matrix<double, 3, 4> p_left = calib.Matrix3x4(left_key);
  const int left_line = calib.Line(left_key);
  PinholeCamera& cam = dataset->rig.left;
  cam.fx = p_left(0, 0);
  cam.fy = p_left(1, 1);
  cam.cx = p_left(0, 2);
  cam.cy = p_left(1, 2);
  const cv::Size size = DatasetImageSize(dataset->left_paths);
  cam.width_px = size.width;
  cam.height_px = size.height;
  std::string why;
  if (!cam.IsValid(&why))
    throw InputError(calib.name(), left_line,
                     "entry '" + left_key + "' gives an invalid camera: " + why);
  if (!(cam.cx >= 0 && cam.cx <= size.width && cam.cy >= 0 && cam.cy <= size.height))
    throw InputError(calib.name(), left_line,
                     fmt::format("entry '{}': principal point ({:g}, {:g}) lies outside the "
                                 "{} x {} images",
                                 left_key, cam.cx, cam.cy, size.width, size.height));
  dataset->rig.baseline_m = 0;
  if (dataset->has_right() && !calib.Has(right_key)) {
    // A monocular calibration beside a folder of right images: usable for mono, so the right
    // images are left out (with a warning) and a stereo run says why it has none.
    dataset->right_unused = calib.name() + " has no entry '" + right_key +
                            "', the camera of the right images (" +
                            fs::path(dataset->right_paths.front()).parent_path().string() + ")";
    dataset->right_paths.clear();
    Logger().warn("{}: right images not used, monocular only", dataset->right_unused);
  }
  if (dataset->has_right()) {
    const Eigen::Matrix<double, 3, 4> p_right = calib.Matrix3x4(right_key);
    const int right_line = calib.Line(right_key);
    constexpr double kTolerancePx = 0.01;
    const std::array<std::pair<const char*, std::array<double, 2>>, 4> shared = {{
        {"fx", {p_left(0, 0), p_right(0, 0)}},
        {"fy", {p_left(1, 1), p_right(1, 1)}},
        {"cx", {p_left(0, 2), p_right(0, 2)}},
        {"cy", {p_left(1, 2), p_right(1, 2)}},
    }};
    for (const auto& [what, values] : shared)
      if (!(std::abs(values[0] - values[1]) <= kTolerancePx))
        throw InputError(calib.name(), right_line,
                         fmt::format("entry '{}': {} {:g} differs from {:g} of '{}' (rectified "
                                     "stereo cameras share fx, fy, cx, cy)",
                                     right_key, what, values[1], values[0], left_key));
    dataset->rig.baseline_m = (p_left(0, 3) - p_right(0, 3)) / cam.fx;
    if (!(dataset->rig.baseline_m > 0))
      throw InputError(
          calib.name(), right_line,
          "stereo baseline from '" + left_key + "' and '" + right_key + "' is not positive");
  }
  if (!dataset->rig.IsValid(&why))
    throw InputError(calib.name(), 0, "calibration gives an invalid camera: " + why);
}

}  // namespace pcr
