// Runs PCR-ORB (stereo, dynamic-point filter on) on a KITTI sequence through the public API and
// prints the trajectory's ATE against the sequence's ground truth.
//   kitti_ate SEQUENCE_DIR [FIRST END]
#include <pcr/api.h>

#include <cstdio>
#include <cstdlib>

int main(int argc, char** argv) {
  if (argc != 2 && argc != 4) {
    std::fprintf(stderr, "usage: %s SEQUENCE_DIR [FIRST END]\n", argv[0]);
    return 2;
  }
  pcr::api::Config config;
  config.filter = true;
  const pcr::api::Source source = pcr::api::Source::Dataset(
      argv[1], argc == 4 ? std::atoll(argv[2]) : 0, argc == 4 ? std::atoll(argv[3]) : 0);
  try {
    const pcr::api::Result result = pcr::api::Run(config, source);
    std::printf("pcr_orb %s: %zu frames, %zu tracked, %zu keyframes\n", pcr::api::Version().c_str(),
                result.stats.frames_in, result.stats.frames_tracked, result.stats.keyframes);
    if (!result.error.empty()) {
      std::fprintf(stderr, "run stopped: %s\n", result.error.c_str());
      return 1;
    }
    if (!result.stats.ate_rmse_m) {
      std::fprintf(stderr, "no ground truth\n");
      return 1;
    }
    std::printf("ATE %.4f m\n", *result.stats.ate_rmse_m);
  } catch (const pcr::api::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
