#!/usr/bin/env bash
# The GPU check, on a machine with the NVIDIA driver and CUDA (the `device` tool's), from the
# repository root, after scripts/device_pack.sh here. Two calls, each within the tool's 64 MiB:
#   scripts/device_run.sh unpack    (carry .device/bin)  unpacks to $PCR_DEVICE_DIR, outside the
#                                   checkout, so that it stays while the machine is warm
#   scripts/device_run.sh check     (carry .device/data) runs, writing logs to $OUT:
#     test_gpu (the CUDA executor and the CUDA LK flow against their CPU twins on real data),
#     bench_yolo's forward pass on cuda and on OpenCV DNN, and bench_pipeline (sequential,
#     pipelined, realtime; on cuda also pipelined with the GPU passes blocking their threads, 3
#     rounds) with the network and the filter's LK flow on cuda, and on the CPU (opencv), on the
#     carried frames, 2 threads. It exits non-zero when test_gpu fails, or when its CUDA tests
#     (YoloCuda, LkCuda) are skipped or none passes: on the device they must run.
set -uo pipefail
cd "$(dirname "$0")/.."
dest=${PCR_DEVICE_DIR:-/root/pcr-gpu}
out=${OUT:-.device/out}
mkdir -p "$out"
case "${1:-}" in
  unpack)
    mkdir -p "$(dirname "$dest")"
    tar -C "$(dirname "$dest")" -xJf .device/bin/pcr-gpu.tar.xz && ls "$dest"
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
    ;;
  check)
    [ -x "$dest/test_gpu" ] || { echo "run '$0 unpack' first (carry .device/bin)"; exit 2; }
    export LD_LIBRARY_PATH="$dest/lib:/usr/local/cuda/lib64:/usr/local/cuda/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    export PCR_SHARED_DIR="$PWD/.device/data"
    seq="$PCR_SHARED_DIR/data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync"
    model="$PCR_SHARED_DIR/models/yolov8n-seg_coco_224x640.onnx"
    # The CUDA tests, the executor's and the LK flow's lowering, and the CPU executors against
    # OpenCV DNN on the real model (YoloTwin/CpuExecutor.RawOutputsMatchOpenCvDnn/twin, /onednn).
    failed=0
    "$dest/test_gpu" --gtest_filter='YoloCuda*:LkCuda*:NetPlan*:LkFlow*:YoloTwin/CpuExecutor.RawOutputsMatchOpenCvDnn/*' \
      2>&1 | tee "$out/test_gpu.log" || { echo "device_run: test_gpu failed"; failed=1; }
    # Here the CUDA tests must run: skipped (no device seen, a build without CUDA) or absent
    # (a filter that matches none) is a failed check, not a pass.
    if grep -E '^\[  SKIPPED \] (YoloCuda|LkCuda)\.' "$out/test_gpu.log"; then
      echo "device_run: the CUDA tests were skipped on the device run"
      failed=1
    fi
    if ! grep -qE '^\[       OK \] (YoloCuda|LkCuda)\.' "$out/test_gpu.log"; then
      echo "device_run: no CUDA test passed"
      failed=1
    fi
    "$dest/bench_yolo" --inference cuda --benchmark_filter='(Forward|Segment)/224x640' 2>&1 |
      tee "$out/bench_yolo_cuda.log"
    "$dest/bench_yolo" --benchmark_filter='(Forward|Segment)/224x640' 2>&1 |
      tee "$out/bench_yolo_opencv.log"
    # cuda: 3 rounds, and a row with the GPU pass blocking its thread (--device-overlap off).
    for inference in cuda opencv; do
      rounds=1
      [ "$inference" = cuda ] && rounds=3
      "$dest/bench_pipeline" "$seq" --threads 2 --model "$model" --model-high none \
        --inference "$inference" --flow "$inference" --repeat "$rounds" 2>&1 |
        tee "$out/bench_pipeline_$inference.log"
    done
    # After the benchmarks, so that their logs come back either way.
    exit "$failed"
    ;;
  *)
    echo "usage: $0 unpack|check"
    exit 2
    ;;
esac
