#include "nodes/feature_nodes.h"

#include <chrono>
#include <stdexcept>
#include <string>

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
  msg->right = source_.load_right(ticket.frame_index);
  for (const cv::Mat* image : {&msg->left, &msg->right}) {
    const char* which = image == &msg->left ? "left" : "right";
    if (image->empty())
      throw std::runtime_error(FrameName(ticket) + ": the " + which + " image is empty");
    if (image->type() != CV_8UC1)
      throw std::runtime_error(FrameName(ticket) + ": the " + which + " image is not CV_8UC1");
  }
  if (msg->left.size() != msg->right.size())
    throw std::runtime_error(FrameName(ticket) + ": left and right images differ in size");
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
