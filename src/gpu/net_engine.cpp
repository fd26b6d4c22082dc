#include "gpu/net_engine.h"

#include <stdexcept>
#include <utility>
#include <vector>

#include "gpu/executor.h"
#include "slam/common/log.h"

namespace pcr::gpu {
namespace {

class NetEngine final : public InferenceEngine {
 public:
  // device_path: the executor takes the graph's device wait (CUDA, and the twin that checks
  // that path); a CPU engine (onednn) is plain CPU work of the calling stage and ignores it.
  NetEngine(std::shared_ptr<const NetPlan> plan, std::unique_ptr<Executor> executor,
            bool device_path)
      : plan_(std::move(plan)), executor_(std::move(executor)), device_path_(device_path) {}

  std::vector<std::vector<int>> OutputShapes() const override {
    std::vector<std::vector<int>> shapes;
    for (const PlanTensor& t : plan_->outputs) shapes.emplace_back(t.shape.begin(), t.shape.end());
    return shapes;
  }

  std::vector<cv::Mat> Forward(const cv::Mat& blob) override {
    const std::vector<int64_t>& in = plan_->input.shape;
    const bool fits = blob.type() == CV_32F && blob.isContinuous() && blob.dims == 4 &&
                      blob.size[0] == in[0] && blob.size[1] == in[1] && blob.size[2] == in[2] &&
                      blob.size[3] == in[3];
    if (!fits) throw std::invalid_argument("NetEngine: the blob does not match the model input");
    std::vector<cv::Mat> mats;
    std::vector<float*> destinations;
    for (const PlanTensor& t : plan_->outputs) {
      const std::vector<int> dims(t.shape.begin(), t.shape.end());
      mats.emplace_back(static_cast<int>(dims.size()), dims.data(), CV_32F);
      destinations.push_back(mats.back().ptr<float>());
    }
    const float* input = blob.ptr<float>();
    if (wait_) {
      // A Launch that throws has not arranged for done(): the wait passes the exception on.
      wait_([&](const DeviceDone& done) { executor_->Launch(input, done); });
    } else {
      executor_->Launch(input, {});
    }
    executor_->Finish(destinations);  // straight into the caller's tensors
    return mats;
  }

  void SetDeviceWait(DeviceWait wait) override {
    if (device_path_) wait_ = std::move(wait);
  }

  std::string Backend() const override { return "pcr-" + executor_->Name(); }

 private:
  std::shared_ptr<const NetPlan> plan_;
  std::unique_ptr<Executor> executor_;
  bool device_path_ = true;
  DeviceWait wait_;  // empty: Finish() blocks
};

}  // namespace

bool IsNetEngineDevice(const std::string& device) {
  return device == kOneDnnDevice || IsEngineDevice(device);
}

std::unique_ptr<InferenceEngine> MakeNetEngine(const std::vector<uint8_t>& model_bytes,
                                               cv::Size input_size, const std::string& device) {
  const bool onednn = device == kOneDnnDevice;
  const int index = onednn ? -1 : EngineDeviceIndex(device, "inference");
  auto plan = std::make_shared<const NetPlan>(
      BuildNetPlan(model_bytes, input_size.height, input_size.width));
  std::unique_ptr<Executor> executor =
      onednn      ? MakeTwinExecutor(plan, MakeOneDnnConvKernels(plan), /*row_steps=*/true)
      : index < 0 ? MakeTwinExecutor(plan)
                  : MakeCudaExecutor(plan, index);
  Logger().info(
      "NetEngine: {} steps ({} fused activations), {:.1f} MiB weights, {:.1f} MiB "
      "activations, on {}",
      plan->steps.size(), plan->fused_activations, ConstantFloats(*plan) * 4.0 / (1 << 20),
      ActivationFloats(*plan) * 4.0 / (1 << 20), executor->Name());
  return std::make_unique<NetEngine>(plan, std::move(executor), /*device_path=*/!onednn);
}

InferenceEngineFactory NetEngineFactory(const std::string& device) {
  if (device == kOneDnnDevice) {
    if (!OneDnnBuilt()) throw std::invalid_argument("inference onednn: this build has no oneDNN");
  } else {
    EngineDeviceIndex(device, "inference");  // reject a bad name now, not at the first model
  }
  return [device](const std::vector<uint8_t>& model_bytes, cv::Size input_size) {
    return MakeNetEngine(model_bytes, input_size, device);
  };
}

}  // namespace pcr::gpu
