#include "nodes/feature_nodes.h"

#include <chrono>
#include <stdexcept>
#include <string>

#include "slam/common/image.h"
#include "slam/common/timing.h"

namespace pcr::nodes {
namespace {

std::string FrameName(const FrameTicket& t) { return "frame " + std::to_string(t.frame_index); }

}  // namespace

ImagesPtr PreprocessNode::operator()(const FrameTicket& ticket) const {
  const auto start = std::chrono::steady_clock::now();
  auto msg = std::make_shared<ImagesMsg>();
  msg->ticket = ticket;
  msg->left = source_.load_left(ticket.frame_index);
  if (!monocular_) msg->right = source_.load_right(ticket.frame_index);
  if (ticket.run_inference && source_.load_left_color)
    msg->left_color = source_.load_left_color(ticket.frame_index);
  // Against the rig's image size (when it has one), else the left image's.
  const cv::Size rig_size(source_.rig.left.width_px, source_.rig.left.height_px);
  const bool has_rig_size = rig_size.width > 0 && rig_size.height > 0;
  auto check = [&](const cv::Mat& image, const char* which, int type, const char* type_name) {
    if (image.empty())
      throw std::runtime_error(FrameName(ticket) + ": the " + which + " image is empty");
    if (image.type() != type)
      throw std::runtime_error(FrameName(ticket) + ": the " + which + " image is not " + type_name);
    const cv::Size expected = has_rig_size ? rig_size : msg->left.size();
    if (image.size() != expected)
      throw std::runtime_error(
          FrameName(ticket) + ": the " + which + " image is " + SizeText(image.size()) + ", but " +
          (has_rig_size ? "the rig's camera is " : "the left one is ") + SizeText(expected));
  };
  check(msg->left, "left", CV_8UC1, "CV_8UC1");
  if (!monocular_) check(msg->right, "right", CV_8UC1, "CV_8UC1");
  if (ticket.run_inference && source_.load_left_color)
    check(msg->left_color, "colour left", CV_8UC3, "CV_8UC3");
  msg->load_ms = MsSince(start);
  return msg;
}

OrbNode::OrbNode(const SlamSystem& slam, Side side, std::vector<const OrbExtractor*> extra)
    : slam_(slam), side_(side), extra_(std::move(extra)) {}

FeaturesPtr OrbNode::operator()(const ImagesPtr& images) const {
  const auto start = std::chrono::steady_clock::now();
  auto msg = std::make_shared<FeaturesMsg>();
  msg->ticket = images->ticket;
  msg->side = side_;
  msg->images = images;
  if (side_ == Side::kRight && slam_.mode() == SlamMode::kMonocular) {
    msg->extract_ms = MsSince(start);
    return msg;  // no right camera: empty features
  }
  const cv::Mat& image = side_ == Side::kLeft ? images->left : images->right;
  const int wanted = images->ticket.settings.orb_features;
  if (wanted == slam_.options().orb.num_features) {
    msg->features = side_ == Side::kLeft ? slam_.ExtractLeft(image) : slam_.ExtractRight(image);
  } else {
    const OrbExtractor* extractor = nullptr;
    for (const OrbExtractor* e : extra_) {
      if (e && e->options().num_features == wanted) extractor = e;
    }
    if (!extractor)
      throw std::invalid_argument("OrbNode: no extractor for " + std::to_string(wanted) +
                                  " features");
    msg->features = extractor->Extract(image);
  }
  msg->extract_ms = MsSince(start);
  return msg;
}

StereoPtr StereoNode::operator()(const FeaturesPtr& left, const FeaturesPtr& right) const {
  if (left->ticket.seq != right->ticket.seq || left->side != Side::kLeft ||
      right->side != Side::kRight)
    throw std::invalid_argument("StereoNode: features of different frames or sides");
  const auto start = std::chrono::steady_clock::now();
  auto msg = std::make_shared<StereoMsg>();
  msg->ticket = left->ticket;
  msg->images = left->images;
  msg->left = left;
  msg->stereo = slam_.MatchStereoFeatures(left->features, right->features);
  msg->orb_right_ms = right->extract_ms;
  msg->match_ms = MsSince(start);
  return msg;
}

}  // namespace pcr::nodes
