// The network executor's lowering (net_plan.h) and its CPU twin on small hand-written ONNX
// graphs, each op against a direct computation written out in the test.
#include "gpu/net_plan.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numeric>
#include <random>

#include "gpu/executor.h"
#include "support/onnx_writer.h"

namespace pcr::gpu {
namespace {

using test::OnnxAttr;
using test::OnnxWriter;

std::vector<float> Random(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> v(n);
  for (float& x : v) x = u(rng);
  return v;
}

// Runs the model on the twin; input is 1 x 3 x h x w.
std::vector<std::vector<float>> RunTwin(const test::Bytes& model, int h, int w,
                                        const std::vector<float>& input,
                                        NetPlan* plan_out = nullptr) {
  auto plan = std::make_shared<const NetPlan>(BuildNetPlan(model, h, w));
  if (plan_out) *plan_out = *plan;
  return MakeTwinExecutor(plan)->Run(input.data());
}

float SiluRef(float x) { return x / (1.0f + std::exp(-x)); }

// Direct convolution, 1 x c x h x w input, weights m x c x k x k.
std::vector<float> ConvRef(const std::vector<float>& x, int c, int h, int w,
                           const std::vector<float>& wt, const std::vector<float>& bias, int m,
                           int k, int stride, int pad, int* ho, int* wo) {
  *ho = (h + 2 * pad - k) / stride + 1;
  *wo = (w + 2 * pad - k) / stride + 1;
  std::vector<float> out(static_cast<size_t>(m) * *ho * *wo);
  for (int o = 0; o < m; ++o) {
    for (int y = 0; y < *ho; ++y) {
      for (int xx = 0; xx < *wo; ++xx) {
        double acc = bias.empty() ? 0.0 : bias[o];
        for (int ci = 0; ci < c; ++ci) {
          for (int ky = 0; ky < k; ++ky) {
            for (int kx = 0; kx < k; ++kx) {
              const int iy = y * stride - pad + ky, ix = xx * stride - pad + kx;
              if (iy < 0 || iy >= h || ix < 0 || ix >= w) continue;
              acc += static_cast<double>(wt[((o * c + ci) * k + ky) * k + kx]) *
                     x[(ci * h + iy) * w + ix];
            }
          }
        }
        out[(o * *ho + y) * *wo + xx] = static_cast<float>(acc);
      }
    }
  }
  return out;
}

void ExpectNear(const std::vector<float>& got, const std::vector<float>& want, float tol) {
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_NEAR(got[i], want[i], tol) << "element " << i;
  }
}

TEST(NetPlan, StridedPaddedConvWithBiasMatchesDirectConvolution) {
  const int h = 7, w = 9, m = 4, k = 3;
  const auto weights = Random(m * 3 * k * k, 1), bias = Random(m, 2), input = Random(3 * h * w, 3);
  const auto model =
      OnnxWriter()
          .Input("x", {1, 3, h, w})
          .Floats("w", {m, 3, k, k}, weights)
          .Floats("b", {m}, bias)
          .Node("Conv", {"x", "w", "b"}, {"y"},
                {OnnxAttr::Ints("kernel_shape", {3, 3}), OnnxAttr::Ints("strides", {2, 2}),
                 OnnxAttr::Ints("pads", {1, 1, 1, 1})})
          .Output("y")
          .Model();
  NetPlan plan;
  const auto out = RunTwin(model, h, w, input, &plan);
  int ho = 0, wo = 0;
  const auto want = ConvRef(input, 3, h, w, weights, bias, m, k, 2, 1, &ho, &wo);
  EXPECT_EQ(plan.outputs[0].shape, (std::vector<int64_t>{1, m, ho, wo}));
  EXPECT_EQ(ho, 4);
  EXPECT_EQ(wo, 5);
  ExpectNear(out[0], want, 1e-5f);
  EXPECT_GT(plan.scratch_size, 0);
}

// The CUDA kernel computes the column matrix by element index, the twin tap by tap: the same
// values in the same places.
TEST(NetPlan, Im2ColByIndexMatchesTapByTap) {
  ConvGeometry g;
  g.c_in = 3;
  g.h_in = 7;
  g.w_in = 9;
  g.c_out = 2;
  g.kh = 3;
  g.kw = 2;
  g.stride_h = 2;
  g.stride_w = 1;
  g.pad_top = 1;
  g.pad_left = 2;
  g.dilation_h = 2;
  g.dilation_w = 1;
  g.h_out = (g.h_in + 2 * g.pad_top - g.dilation_h * (g.kh - 1) - 1) / g.stride_h + 1;
  g.w_out = (g.w_in + 2 * g.pad_left - g.dilation_w * (g.kw - 1) - 1) / g.stride_w + 1;
  const auto input = Random(3 * 7 * 9, 21);
  int64_t index = 0, zeros = 0;
  for (int c = 0; c < g.c_in; ++c) {
    for (int ky = 0; ky < g.kh; ++ky) {
      for (int kx = 0; kx < g.kw; ++kx) {
        for (int oy = 0; oy < g.h_out; ++oy) {
          for (int ox = 0; ox < g.w_out; ++ox, ++index) {
            const float tap = Im2ColTap(input.data(), g, c, ky, kx, oy, ox);
            ASSERT_EQ(Im2ColAt(input.data(), g, index), tap) << index;
            zeros += tap == 0.0f;
          }
        }
      }
    }
  }
  EXPECT_EQ(index, ColRows(g) * ColCols(g));
  EXPECT_GT(zeros, 0);  // the padding was exercised
}

TEST(NetPlan, ConvSigmoidMulIsFusedIntoOneSiluStep) {
  const int h = 5, w = 6, m = 2;
  const auto weights = Random(m * 3, 4), input = Random(3 * h * w, 5);
  const auto model = OnnxWriter()
                         .Input("x", {1, 3, h, w})
                         .Floats("w", {m, 3, 1, 1}, weights)
                         .Node("Conv", {"x", "w"}, {"c"}, {OnnxAttr::Ints("kernel_shape", {1, 1})})
                         .Node("Sigmoid", {"c"}, {"s"})
                         .Node("Mul", {"c", "s"}, {"y"})
                         .Output("y")
                         .Model();
  NetPlan plan;
  const auto out = RunTwin(model, h, w, input, &plan);
  EXPECT_EQ(plan.fused_activations, 1);
  EXPECT_EQ(plan.steps.size(), 1u);
  EXPECT_EQ(plan.scratch_size, 0);  // pointwise: no column matrix
  int ho = 0, wo = 0;
  auto want = ConvRef(input, 3, h, w, weights, {}, m, 1, 1, 0, &ho, &wo);
  for (float& v : want) v = SiluRef(v);
  ExpectNear(out[0], want, 1e-5f);
}

TEST(NetPlan, SigmoidUsedElsewhereIsNotFused) {
  const auto weights = Random(3 * 3, 6), input = Random(3 * 4 * 4, 7);
  const auto model = OnnxWriter()
                         .Input("x", {1, 3, 4, 4})
                         .Floats("w", {3, 3, 1, 1}, weights)
                         .Node("Conv", {"x", "w"}, {"c"})
                         .Node("Sigmoid", {"c"}, {"s"})
                         .Node("Mul", {"c", "s"}, {"y"})
                         .Output("y")
                         .Output("s")
                         .Model();
  NetPlan plan;
  const auto out = RunTwin(model, 4, 4, input, &plan);
  EXPECT_EQ(plan.fused_activations, 0);
  EXPECT_EQ(plan.steps.size(), 3u);
  // Both outputs against the test's own convolution, so a wrong Conv step is caught too.
  int ho = 0, wo = 0;
  const auto conv = ConvRef(input, 3, 4, 4, weights, {}, 3, 1, 1, 0, &ho, &wo);
  ASSERT_EQ(out.size(), 2u);
  ASSERT_EQ(out[0].size(), conv.size());
  ASSERT_EQ(out[1].size(), conv.size());
  for (size_t i = 0; i < conv.size(); ++i) {
    const float sig = 1.0f / (1.0f + std::exp(-conv[i]));
    EXPECT_NEAR(out[1][i], sig, 1e-5f) << "sigmoid, element " << i;
    EXPECT_NEAR(out[0][i], conv[i] * sig, 1e-5f) << "product, element " << i;
  }
}

TEST(NetPlan, ConvTransposeStrideTwoMatchesScatterDefinition) {
  const int h = 3, w = 4, cout = 2, k = 2;
  const auto weights = Random(3 * cout * k * k, 8), bias = Random(cout, 9),
             input = Random(3 * h * w, 10);
  const auto model =
      OnnxWriter()
          .Input("x", {1, 3, h, w})
          .Floats("w", {3, cout, k, k}, weights)
          .Floats("b", {cout}, bias)
          .Node("ConvTranspose", {"x", "w", "b"}, {"y"},
                {OnnxAttr::Ints("kernel_shape", {2, 2}), OnnxAttr::Ints("strides", {2, 2})})
          .Output("y")
          .Model();
  const auto out = RunTwin(model, h, w, input);
  std::vector<float> want(static_cast<size_t>(cout) * 2 * h * 2 * w);
  for (int m = 0; m < cout; ++m) {
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        for (int ky = 0; ky < k; ++ky) {
          for (int kx = 0; kx < k; ++kx) {
            double acc = bias[m];
            for (int c = 0; c < 3; ++c) {
              acc += static_cast<double>(weights[((c * cout + m) * k + ky) * k + kx]) *
                     input[(c * h + y) * w + x];
            }
            want[(m * 2 * h + 2 * y + ky) * 2 * w + 2 * x + kx] = static_cast<float>(acc);
          }
        }
      }
    }
  }
  ExpectNear(out[0], want, 1e-5f);
}

TEST(NetPlan, BroadcastArithmeticFollowsNumpyRules) {
  // x (1x3x2x2) - c (3x1x1), then / 2 (scalar), then * x, + a row (2).
  const std::vector<float> input = Random(12, 11);
  const std::vector<float> c = {1.0f, -2.0f, 0.5f}, row = {10.0f, 20.0f};
  const auto model = OnnxWriter()
                         .Input("x", {1, 3, 2, 2})
                         .Floats("c", {3, 1, 1}, c)
                         .Floats("two", {}, {2.0f})
                         .Floats("row", {2}, row)
                         .Node("Sub", {"x", "c"}, {"a"})
                         .Node("Div", {"a", "two"}, {"b"})
                         .Node("Mul", {"b", "x"}, {"d"})
                         .Node("Add", {"row", "d"}, {"y"})
                         .Output("y")
                         .Model();
  const auto out = RunTwin(model, 2, 2, input);
  std::vector<float> want(12);
  for (int ch = 0; ch < 3; ++ch) {
    for (int i = 0; i < 4; ++i) {
      const float x = input[ch * 4 + i];
      want[ch * 4 + i] = row[i % 2] + (x - c[ch]) / 2.0f * x;
    }
  }
  ExpectNear(out[0], want, 1e-6f);
}

TEST(NetPlan, ConcatSplitAndSliceMoveTheRightChannels) {
  std::vector<float> input(3 * 2 * 2);
  std::iota(input.begin(), input.end(), 0.0f);  // channel c holds 4c .. 4c+3
  const auto model = OnnxWriter()
                         .Input("x", {1, 3, 2, 2})
                         .Ints("sizes", {2}, {1, 2})
                         .Node("Split", {"x", "sizes"}, {"p", "q"}, {OnnxAttr::Int("axis", 1)})
                         .Node("Concat", {"q", "p", "q"}, {"cat"}, {OnnxAttr::Int("axis", 1)})
                         .Ints("starts", {1}, {1})
                         .Ints("ends", {1}, {100})
                         .Ints("axes", {1}, {1})
                         .Ints("steps", {1}, {2})
                         .Node("Slice", {"cat", "starts", "ends", "axes", "steps"}, {"y"})
                         .Output("y")
                         .Output("cat")
                         .Model();
  NetPlan plan;
  const auto out = RunTwin(model, 2, 2, input, &plan);
  // cat = channels [1, 2, 0, 1, 2]; slice 1::2 along channels = [2, 1].
  EXPECT_EQ(plan.outputs[1].shape, (std::vector<int64_t>{1, 5, 2, 2}));
  EXPECT_EQ(plan.outputs[0].shape, (std::vector<int64_t>{1, 2, 2, 2}));
  const std::vector<int> cat_channels = {1, 2, 0, 1, 2};
  for (int k = 0; k < 5; ++k) {
    for (int i = 0; i < 4; ++i) EXPECT_EQ(out[1][k * 4 + i], 4.0f * cat_channels[k] + i);
  }
  const std::vector<int> slice_channels = {2, 1};
  for (int k = 0; k < 2; ++k) {
    for (int i = 0; i < 4; ++i) EXPECT_EQ(out[0][k * 4 + i], 4.0f * slice_channels[k] + i);
  }
}

TEST(NetPlan, MaxPoolIgnoresPaddingAndResizeRepeatsPixels) {
  const std::vector<float> input = Random(3 * 4 * 5, 12);
  const auto model =
      OnnxWriter()
          .Input("x", {1, 3, 4, 5})
          .Node("MaxPool", {"x"}, {"p"},
                {OnnxAttr::Ints("kernel_shape", {5, 5}), OnnxAttr::Ints("pads", {2, 2, 2, 2}),
                 OnnxAttr::Ints("strides", {1, 1})})
          .Floats("scales", {4}, {1.0f, 1.0f, 2.0f, 2.0f})
          .Node("Resize", {"x", "", "scales"}, {"r"},
                {OnnxAttr::String("mode", "nearest"),
                 OnnxAttr::String("coordinate_transformation_mode", "asymmetric"),
                 OnnxAttr::String("nearest_mode", "floor")})
          .Output("p")
          .Output("r")
          .Model();
  const auto out = RunTwin(model, 4, 5, input);
  for (int c = 0; c < 3; ++c) {
    for (int y = 0; y < 4; ++y) {
      for (int x = 0; x < 5; ++x) {
        float best = -1e30f;
        for (int yy = std::max(0, y - 2); yy <= std::min(3, y + 2); ++yy) {
          for (int xx = std::max(0, x - 2); xx <= std::min(4, x + 2); ++xx) {
            best = std::max(best, input[(c * 4 + yy) * 5 + xx]);
          }
        }
        EXPECT_EQ(out[0][(c * 4 + y) * 5 + x], best);
      }
    }
    for (int y = 0; y < 8; ++y) {
      for (int x = 0; x < 10; ++x) {
        EXPECT_EQ(out[1][(c * 8 + y) * 10 + x], input[(c * 4 + y / 2) * 5 + x / 2]);
      }
    }
  }
}

TEST(NetPlan, ReshapeTransposeSoftmaxAsInTheYoloDflHead) {
  // x (1x3x2x4) viewed as 1 x 2 x 3 x 4 (Reshape with 0 and -1), transposed to 1 x 3 x 2 x 4,
  // softmax over axis 1.
  const std::vector<float> input = Random(24, 13);
  const auto model = OnnxWriter()
                         .Input("x", {1, 3, 2, 4})
                         .Ints("shape", {4}, {0, 2, -1, 4})
                         .Node("Reshape", {"x", "shape"}, {"r"})
                         .Node("Transpose", {"r"}, {"t"}, {OnnxAttr::Ints("perm", {0, 2, 1, 3})})
                         .Node("Softmax", {"t"}, {"y"}, {OnnxAttr::Int("axis", 1)})
                         .Output("y")
                         .Model();
  NetPlan plan;
  const auto out = RunTwin(model, 2, 4, input, &plan);
  EXPECT_EQ(plan.steps.size(), 2u);  // the Reshape is a view
  ASSERT_EQ(out[0].size(), 24u);
  // t[0, a, b, c] = r[0, b, a, c] = x flat[(b * 3 + a) * 4 + c].
  for (int b = 0; b < 2; ++b) {
    for (int c = 0; c < 4; ++c) {
      double sum = 0;
      for (int a = 0; a < 3; ++a) sum += std::exp(input[(b * 3 + a) * 4 + c]);
      for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(out[0][(a * 2 + b) * 4 + c], std::exp(input[(b * 3 + a) * 4 + c]) / sum, 1e-6);
      }
    }
  }
}

TEST(NetPlan, UnsupportedOpsAndBadShapesNameTheNode) {
  const auto gather = OnnxWriter()
                          .Input("x", {1, 3, 2, 2})
                          .Ints("i", {1}, {0})
                          .Node("Gather", {"x", "i"}, {"y"})
                          .Output("y")
                          .Model();
  try {
    BuildNetPlan(gather, 2, 2);
    FAIL() << "Gather accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("Gather_0"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("unsupported op"), std::string::npos) << e.what();
  }
  const auto grouped = OnnxWriter()
                           .Input("x", {1, 3, 2, 2})
                           .Floats("w", {3, 1, 1, 1}, {1, 1, 1})
                           .Node("Conv", {"x", "w"}, {"y"}, {OnnxAttr::Int("group", 3)})
                           .Output("y")
                           .Model();
  EXPECT_THROW(BuildNetPlan(grouped, 2, 2), std::invalid_argument);
  const auto mismatch = OnnxWriter()
                            .Input("x", {1, 3, 2, 2})
                            .Floats("c", {3}, {1, 2, 3})
                            .Node("Add", {"x", "c"}, {"y"})
                            .Output("y")
                            .Model();
  EXPECT_THROW(BuildNetPlan(mismatch, 2, 2), std::invalid_argument);  // 2 vs 3 on the last axis
  // A model with a fixed input size refuses another size.
  const auto fixed =
      OnnxWriter().Input("x", {1, 3, 2, 2}).Node("Sigmoid", {"x"}, {"y"}).Output("y").Model();
  EXPECT_NO_THROW(BuildNetPlan(fixed, 2, 2));
  EXPECT_THROW(BuildNetPlan(fixed, 4, 4), std::invalid_argument);
  EXPECT_THROW(BuildNetPlan(test::Str("not a model"), 2, 2), std::invalid_argument);
  // An int8 weight (type 3, as in dynamically quantized exports) used by a Conv.
  const auto weight =
      test::Cat({test::VarintField(1, 1), test::VarintField(1, 3), test::VarintField(1, 1),
                 test::VarintField(1, 1), test::VarintField(2, 3),
                 test::BytesField(8, test::Str("w")), test::BytesField(9, {1, 2, 3})});
  const auto int8_model = OnnxWriter()
                              .Input("x", {1, 3, 2, 2})
                              .RawInitializer(weight)
                              .Node("Conv", {"x", "w"}, {"y"})
                              .Output("y")
                              .Model();
  try {
    BuildNetPlan(int8_model, 2, 2);
    FAIL() << "an int8 weight was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("data type 3"), std::string::npos) << e.what();
  }
}

TEST(NetPlan, LaunchThenFinishWritesTheOutputsAndCallsDoneOnce) {
  const auto model = OnnxWriter()
                         .Input("x", {1, 3, 2, 2})
                         .Node("Sigmoid", {"x"}, {"y"})
                         .Node("Split", {"y"}, {"a", "b"},
                               {OnnxAttr::Int("axis", 1), OnnxAttr::Ints("split", {1, 2})})
                         .Output("a")
                         .Output("b")
                         .Model();
  auto plan = std::make_shared<const NetPlan>(BuildNetPlan(model, 2, 2));
  const auto input = Random(12, 9);
  auto executor = MakeTwinExecutor(plan);
  const auto want = executor->Run(input.data());
  ASSERT_EQ(want.size(), 2u);
  std::vector<float> a(4, -7.0f), b(8, -7.0f);
  int dones = 0;
  executor->Launch(input.data(), [&dones] { ++dones; });
  EXPECT_EQ(dones, 1);  // the twin: before Launch returns
  executor->Finish({a.data(), b.data()});
  EXPECT_EQ(a, want[0]);
  EXPECT_EQ(b, want[1]);
  for (size_t i = 0; i < 4; ++i) EXPECT_FLOAT_EQ(a[i], 1.0f / (1.0f + std::exp(-input[i])));
  EXPECT_EQ(dones, 1);
  EXPECT_THROW(executor->Finish({a.data()}), std::invalid_argument);  // one per output
}

TEST(NetPlan, CudaAbsenceIsReportedNotFatal) {
  std::string why;
  const int devices = CudaDeviceCount(&why);
  if (devices > 0) GTEST_SKIP() << "a CUDA device is present; see the twin comparison test";
  EXPECT_FALSE(why.empty());
  const auto model =
      OnnxWriter().Input("x", {1, 3, 2, 2}).Node("Sigmoid", {"x"}, {"y"}).Output("y").Model();
  auto plan = std::make_shared<const NetPlan>(BuildNetPlan(model, 2, 2));
  EXPECT_THROW(MakeCudaExecutor(plan), std::runtime_error);
}

// Found by fuzz/fuzz_onnx.cpp: each was a crash, an uncaught std::out_of_range or undefined
// behaviour before it was fixed.
TEST(NetPlan, FuzzFindingsAreRefusedOrComputedCleanly) {
  // An empty slice divided by a scalar: the 0 dim broadcasts to 0 (was 1: a read of nothing).
  const auto empty = OnnxWriter()
                         .Input("x", {1, 3, 2, 2})
                         .Ints("starts", {1}, {int64_t{1} << 33})
                         .Ints("ends", {1}, {int64_t{1} << 55})
                         .Ints("axes", {1}, {1})
                         .Node("Slice", {"x", "starts", "ends", "axes"}, {"s"})
                         .Floats("two", {}, {2.0f})
                         .Node("Div", {"s", "two"}, {"y"})
                         .Output("y")
                         .Model();
  NetPlan plan;
  const auto out = RunTwin(empty, 2, 2, std::vector<float>(12, 1.0f), &plan);
  EXPECT_EQ(plan.outputs[0].shape, (std::vector<int64_t>{1, 0, 2, 2}));
  EXPECT_TRUE(out[0].empty());
  // A Conv without an output.
  const auto no_output = OnnxWriter()
                             .Input("x", {1, 3, 2, 2})
                             .Floats("w", {1, 3, 1, 1}, {1, 1, 1})
                             .Node("Conv", {"x", "w"}, {})
                             .Output("x")
                             .Model();
  EXPECT_THROW(BuildNetPlan(no_output, 2, 2), std::invalid_argument);
  // Shapes whose element count overflows, negative split sizes, shape arithmetic that overflows.
  const auto huge = OnnxWriter()
                        .Input("x", {1, 3, 2, 2})
                        .Ints("shape", {4}, {int64_t{1} << 40, int64_t{1} << 40, -1, 1})
                        .Node("Reshape", {"x", "shape"}, {"y"})
                        .Output("y")
                        .Model();
  EXPECT_THROW(BuildNetPlan(huge, 2, 2), std::invalid_argument);
  const auto negative_split =
      OnnxWriter()
          .Input("x", {1, 3, 2, 2})
          .Ints("sizes", {2}, {-1, 4})
          .Node("Split", {"x", "sizes"}, {"p", "q"}, {OnnxAttr::Int("axis", 1)})
          .Output("q")
          .Model();
  EXPECT_THROW(BuildNetPlan(negative_split, 2, 2), std::invalid_argument);
  const auto overflow = OnnxWriter()
                            .Input("x", {1, 3, 2, 2})
                            .Ints("a", {1}, {int64_t{1} << 62})
                            .Node("Mul", {"a", "a"}, {"b"})
                            .Node("Reshape", {"x", "b"}, {"y"})
                            .Output("y")
                            .Model();
  EXPECT_THROW(BuildNetPlan(overflow, 2, 2), std::invalid_argument);
  const auto wild_pads =
      OnnxWriter()
          .Input("x", {1, 3, 2, 2})
          .Node("MaxPool", {"x"}, {"y"},
                {OnnxAttr::Ints("kernel_shape", {2, 2}),
                 OnnxAttr::Ints("pads", {int64_t{1} << 40, 0, int64_t{1} << 40, 0})})
          .Output("y")
          .Model();
  EXPECT_THROW(BuildNetPlan(wild_pads, 2, 2), std::invalid_argument);
  // A kernel larger than its padded input, with stride 2: integer division would round the
  // negative span up to one output row and column.
  const auto small_conv =
      OnnxWriter()
          .Input("x", {1, 3, 1, 1})
          .Floats("w", {1, 3, 2, 2}, std::vector<float>(12, 1.0f))
          .Node("Conv", {"x", "w"}, {"y"},
                {OnnxAttr::Ints("kernel_shape", {2, 2}), OnnxAttr::Ints("strides", {2, 2})})
          .Output("y")
          .Model();
  EXPECT_THROW(BuildNetPlan(small_conv, 1, 1), std::invalid_argument);
  const auto small_pool =
      OnnxWriter()
          .Input("x", {1, 3, 1, 1})
          .Node("MaxPool", {"x"}, {"y"},
                {OnnxAttr::Ints("kernel_shape", {2, 2}), OnnxAttr::Ints("strides", {2, 2})})
          .Output("y")
          .Model();
  EXPECT_THROW(BuildNetPlan(small_pool, 1, 1), std::invalid_argument);
  // Initializers of data type 0 (undefined) as a Conv bias and as a graph output.
  const auto undefined = test::Cat(
      {test::VarintField(1, 1), test::VarintField(2, 0), test::BytesField(8, test::Str("u"))});
  const auto undefined_bias = OnnxWriter()
                                  .Input("x", {1, 3, 2, 2})
                                  .Floats("w", {1, 3, 1, 1}, {1, 1, 1})
                                  .RawInitializer(undefined)
                                  .Node("Conv", {"x", "w", "u"}, {"y"})
                                  .Output("y")
                                  .Model();
  EXPECT_THROW(BuildNetPlan(undefined_bias, 2, 2), std::invalid_argument);
  const auto undefined_output =
      OnnxWriter().Input("x", {1, 3, 2, 2}).RawInitializer(undefined).Output("u").Model();
  EXPECT_THROW(BuildNetPlan(undefined_output, 2, 2), std::invalid_argument);
}

}  // namespace
}  // namespace pcr::gpu
