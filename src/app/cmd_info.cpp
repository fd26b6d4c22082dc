#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <string>

#include "app/commands.h"
#include "driver/binary_file.h"
#include "gpu/executor.h"
#include "gpu/net_plan.h"
#include "io/dataset.h"
#include "io/kitti_raw.h"
#include "slam/common/error.h"
#include "slam/dynamic/onnx_model.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace pcr::app {
namespace {

// A raw drive's OXTS accuracy fields and the path length by the other ground truth, so that the
// two can be compared (nothing for other datasets).
void PrintOxtsAccuracy(const Dataset& dataset, RawTruth truth) {
  if (dataset.left_paths.empty()) return;
  // The records of the images' own frame numbers (a clip may start after 0 or have gaps).
  const std::vector<OxtsPacket> packets = ReadOxtsPackets(dataset.root, dataset.frame_numbers);
  if (packets.empty()) return;
  double pos_lo = INFINITY, pos_hi = -INFINITY, vel_lo = INFINITY, vel_hi = -INFINITY;
  for (const OxtsPacket& p : packets) {
    pos_lo = std::min(pos_lo, p.pos_accuracy_m);
    pos_hi = std::max(pos_hi, p.pos_accuracy_m);
    vel_lo = std::min(vel_lo, p.vel_accuracy_mps);
    vel_hi = std::max(vel_hi, p.vel_accuracy_mps);
  }
  fmt::print("OXTS accuracy: position {:.2f}-{:.2f} m, velocity {:.3f}-{:.3f} m/s\n", pos_lo,
             pos_hi, vel_lo, vel_hi);
  const RawTruth other = truth == RawTruth::kGps ? RawTruth::kIns : RawTruth::kGps;
  const Dataset alternative = OpenDataset(dataset.root, KittiCameras::kGray, other);
  if (alternative.ground_truth)
    fmt::print("path length:   {:.3f} m by --raw-truth {}\n", PathLength(*alternative.ground_truth),
               ToString(other));
}

void PrintInfo(const std::string& path, bool color, const std::string& raw_truth) {
  const RawTruth truth = ParseRawTruth(raw_truth);
  const Dataset dataset =
      OpenDataset(path, color ? KittiCameras::kColor : KittiCameras::kGray, truth);
  const PinholeCamera& cam = dataset.rig.left;
  const double duration_s = dataset.DurationSeconds();
  fmt::print("name:          {}\n", dataset.name);
  fmt::print("root:          {}\n", dataset.root);
  fmt::print("frames:        {}\n", dataset.size());
  fmt::print("image size:    {} x {} px\n", cam.width_px, cam.height_px);
  fmt::print("intrinsics:    fx {:.4f} fy {:.4f} cx {:.4f} cy {:.4f} px\n", cam.fx, cam.fy, cam.cx,
             cam.cy);
  if (dataset.has_right())
    fmt::print("stereo:        yes, baseline {:.4f} m\n", dataset.rig.baseline_m);
  else
    fmt::print("stereo:        no (monocular)\n");
  fmt::print("colour left:   {}\n", dataset.has_color() ? "yes" : "no");
  fmt::print("duration:      {:.3f} s\n", duration_s);
  if (dataset.size() > 1 && duration_s > 0)
    fmt::print("frame rate:    {:.3f} Hz (mean)\n", (dataset.size() - 1) / duration_s);
  if (dataset.ground_truth) {
    fmt::print("ground truth:  yes ({})\n", dataset.ground_truth_source);
    fmt::print("path length:   {:.3f} m\n", PathLength(*dataset.ground_truth));
    PrintOxtsAccuracy(dataset, truth);
  } else {
    fmt::print("ground truth:  no\n");
  }
}

// What a YOLOv8(-seg) ONNX export is and which engines can run it.
void PrintModelInfo(const std::string& path) {
  // A regular file only: a device or a FIFO would be read until memory runs out.
  const std::vector<uint8_t> bytes = driver::ReadFileBytes(path, "model");
  OnnxModel model;
  try {
    model = ParseOnnxModel(bytes);
  } catch (const std::invalid_argument& e) {
    throw InputError(path, 0, std::string("cannot read it as an ONNX model: ") + e.what());
  }
  fmt::print("model:         {} ({:.1f} MiB)\n", path, bytes.size() / 1048576.0);
  fmt::print("opset:         {}\n", model.opset);
  for (const OnnxValueInfo& v : model.inputs)
    fmt::print("input:         {} {}\n", v.name, OnnxDimsText(v.dims));
  for (const OnnxValueInfo& v : model.outputs)
    fmt::print("output:        {} {}\n", v.name, OnnxDimsText(v.dims));
  std::map<std::string, int> ops;
  for (const OnnxNode& n : model.nodes) ++ops[n.op_type];
  std::string op_text;
  for (const auto& [op, count] : ops)
    op_text += fmt::format("{}{} {}", op_text.empty() ? "" : ", ", op, count);
  fmt::print("nodes:         {} ({})\n", model.nodes.size(), op_text);

  YoloOptions options;
  options.model_path = path;
  options.allow_cuda = false;
  cv::Size input_size = options.dynamic_input_size;
  if (!model.inputs.empty() && model.inputs[0].dims.size() == 4 && model.inputs[0].dims[2] > 0 &&
      model.inputs[0].dims[3] > 0) {
    input_size = cv::Size(static_cast<int>(model.inputs[0].dims[3]),
                          static_cast<int>(model.inputs[0].dims[2]));
  }
  // An engine runs the model only if its outputs have a YOLOv8 layout the segmenter accepts for
  // the 80 COCO names (the commands' only names): InspectYoloOutputs, the segmenter's own check,
  // for every engine.
  const int num_class_names = static_cast<int>(CocoClassNames().size());
  const auto print_layout = [](const YoloOutputLayout& l) {
    fmt::print("YOLO layout:   {} classes, {} mask coefficients, {} anchors, prototypes {}x{}\n",
               l.num_classes, l.num_mask_coeffs, l.num_anchors, l.proto_size.width,
               l.proto_size.height);
  };
  bool layout_printed = false;
  try {
    const YoloSegmenter segmenter(options);
    input_size = segmenter.input_size();
    print_layout(segmenter.layout());
    layout_printed = true;
    fmt::print("opencv:        runs ({})\n", segmenter.backend());
  } catch (const std::exception& e) {
    fmt::print("opencv:        cannot run it: {}\n", e.what());
  }
  // Why the executor (twin, onednn, cuda) cannot run the model; empty when it can.
  std::string executor_why;
  try {
    const gpu::NetPlan plan = gpu::BuildNetPlan(bytes, input_size.height, input_size.width);
    std::vector<std::vector<int>> output_shapes;
    for (const gpu::PlanTensor& t : plan.outputs)
      output_shapes.emplace_back(t.shape.begin(), t.shape.end());
    try {
      const YoloOutputLayout layout = InspectYoloOutputs(output_shapes, num_class_names, path);
      if (!layout_printed) print_layout(layout);
      layout_printed = true;
    } catch (const InputError& e) {
      executor_why = e.what();
    }
    if (!executor_why.empty()) {
      fmt::print("pcr executor:  cannot run it: {}\n", executor_why);
    } else {
      fmt::print(
          "pcr executor:  runs at {}x{}: {} steps ({} fused activations), {:.1f} MiB weights, "
          "{:.1f} MiB activations\n",
          input_size.width, input_size.height, plan.steps.size(), plan.fused_activations,
          gpu::ConstantFloats(plan) * 4.0 / 1048576.0,
          gpu::ActivationFloats(plan) * 4.0 / 1048576.0);
    }
    if (!gpu::OneDnnBuilt()) {
      fmt::print("onednn:        unavailable (this build has no oneDNN: install libdnnl-dev)\n");
    } else if (!executor_why.empty()) {
      fmt::print("onednn:        cannot run it: {}\n", executor_why);
    } else {
      try {
        // Builds every convolution's primitive.
        gpu::MakeOneDnnConvKernels(std::make_shared<const gpu::NetPlan>(plan));
        fmt::print("onednn:        runs (--inference onednn; auto's choice without CUDA)\n");
      } catch (const std::exception& e) {
        fmt::print("onednn:        cannot run it: {}\n", e.what());
      }
    }
  } catch (const std::invalid_argument& e) {
    executor_why = e.what();
    fmt::print("pcr executor:  cannot run it: {}\n", executor_why);
    fmt::print("onednn:        cannot run it (the pcr executor's reason)\n");
  }
  if (!layout_printed) {
    // Neither engine ran it: the layout its declared outputs would have, or why it is none.
    std::vector<std::vector<int>> declared;
    for (const OnnxValueInfo& v : model.outputs) {
      std::vector<int>& dims = declared.emplace_back();
      for (const auto d : v.dims) dims.push_back(static_cast<int>(d));
    }
    try {
      print_layout(InspectYoloOutputs(declared, num_class_names, path));
    } catch (const std::exception& e) {
      fmt::print("YOLO layout:   none the segmenter takes: {}\n", e.what());
    }
  }
  std::string why;
  const int devices = gpu::CudaDeviceCount(&why);
  if (devices > 0 && !executor_why.empty()) {
    fmt::print("cuda:          {} device(s), but cannot run it (the pcr executor's reason)\n",
               devices);
  } else if (devices > 0) {
    fmt::print("cuda:          {} device(s): --inference cuda\n", devices);
  } else {
    fmt::print("cuda:          unavailable ({})\n", why);
  }
}

}  // namespace

void AddRawTruthOption(CLI::App* cmd, std::string* raw_truth) {
  cmd->add_option("--raw-truth", *raw_truth,
                  "raw drives' ground-truth positions: ins (OXTS velocities integrated) or gps "
                  "(OXTS latitude/longitude/altitude, as the KITTI devkit)")
      ->check(CLI::IsMember({"ins", "gps"}))
      ->capture_default_str();
}

void AddInfoCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "info",
      "Describe a KITTI odometry sequence or raw drive (calibration, frames, ground truth), or a "
      "YOLOv8-seg ONNX model (layout, ops, which inference engines run it)");
  auto path = std::make_shared<std::string>();
  auto model = std::make_shared<std::string>();
  auto color = std::make_shared<bool>(false);
  auto raw_truth = std::make_shared<std::string>("ins");
  auto* sequence = cmd->add_option(
      "--sequence,-s", *path,
      "Odometry sequence dir (sequences/NN) or raw drive dir (DATE/DATE_drive_NNNN_sync)");
  auto* model_option = cmd->add_option("--model", *model, "a YOLOv8(-seg) ONNX export");
  sequence->excludes(model_option);
  auto* color_option = cmd->add_flag("--color", *color,
                                     "Use the colour cameras (2/3) instead of the grey ones (0/1)");
  AddRawTruthOption(cmd, raw_truth.get());
  // A model has no cameras nor ground truth: those options would do nothing.
  model_option->excludes(color_option);
  model_option->excludes(cmd->get_option("--raw-truth"));
  cmd->callback([path, model, color, raw_truth] {
    if (!model->empty()) {
      PrintModelInfo(*model);
    } else if (!path->empty()) {
      PrintInfo(*path, *color, *raw_truth);
    } else {
      throw ConfigError("info needs --sequence DIR or --model FILE.onnx");
    }
  });
}

}  // namespace pcr::app
