#!/usr/bin/env bash
# ThreadSanitizer check of the flow graph: configures the `tsan` CMake preset (build-tsan,
# -fsanitize=thread, RelWithDebInfo), builds pcr_orb only, and runs `pcr_orb pipeline` with
# YOLOv8n-seg 224x640 and the multi-stage filter over the first frames of KITTI raw drive 0005
# under TSAN_OPTIONS=halt_on_error=1 (the first report stops the run with exit code 66).
#   scripts/tsan.sh [POLICY ...]     (default: pipelined; e.g. scripts/tsan.sh pipelined realtime)
# Environment: PCR_SHARED_DIR (default ../shared), PCR_TSAN_FRAMES (default 0:20),
# PCR_TSAN_INFERENCE (--inference, default opencv; `twin` runs the network executor through
# the graph's device wait, which TSAN builds implement by blocking: TSAN cannot follow the
# stack switches of TBB's task suspension),
# PCR_TSAN_FLOW (--flow, default opencv; `twin` runs the filter's LK passes through the
# graph's device wait the same way),
# PCR_JOBS (build jobs, default nproc),
# PCR_TSAN_SEQUENCE (a sequence that comes back to its start, e.g. `pcr_orb synth --route loop`
# output: run it instead of drive 0005, all its frames unless PCR_TSAN_FRAMES is set, without
# YOLO and the filter, so that loop closing's lane, its corrections and global BA run under TSAN),
# PCR_TSAN_SET (space-separated section.key=value settings, each passed as --set, e.g.
# `loop.sequence_length=12`).
# oneTBB and OpenCV come from Debian and are not instrumented: scripts/tsan.supp suppresses
# reports whose frames lie in those libraries only (see the file); reports in our code are not
# suppressed. Exit status 0 means no report.
set -euo pipefail
cd "$(dirname "$0")/.."
shared=${PCR_SHARED_DIR:-$(cd .. && pwd)/shared}
frames=${PCR_TSAN_FRAMES:-0:20}
[ -n "${PCR_TSAN_SEQUENCE:-}" ] && frames=${PCR_TSAN_FRAMES:-}
inference=${PCR_TSAN_INFERENCE:-opencv}
flow=${PCR_TSAN_FLOW:-opencv}
policies=("$@")
[ ${#policies[@]} -eq 0 ] && policies=(pipelined)
drive="$shared/data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync"
model="$shared/models/yolov8n-seg_coco_224x640.onnx"
run_args=(--config config/kitti03.yaml --segmenter yolo --model "$model" --filter on)
if [ -n "${PCR_TSAN_SEQUENCE:-}" ]; then
  drive=$PCR_TSAN_SEQUENCE
  run_args=(--segmenter none --filter off --loop on)
fi
[ -n "$frames" ] && run_args+=(--frames "$frames")
for setting in ${PCR_TSAN_SET:-}; do run_args+=(--set "$setting"); done
if [ ! -d "$drive" ] || [ ! -f "$model" ]; then
  echo "tsan: needs $drive and $model" >&2
  exit 2
fi

cmake --preset tsan >/dev/null
ninja -C build-tsan -j"${PCR_JOBS:-$(nproc)}" pcr_orb

opts="halt_on_error=1 second_deadlock_stack=1 history_size=4 print_suppressions=1"
export TSAN_OPTIONS="$opts suppressions=$PWD/scripts/tsan.supp ${TSAN_OPTIONS:-}"
status=0
for policy in "${policies[@]}"; do
  log=build-tsan/tsan_${policy}.log
  echo "tsan: pcr_orb pipeline --sequence $drive ${run_args[*]} --policy $policy, log in $log"
  set +e
  build-tsan/src/pcr_orb pipeline --sequence "$drive" "${run_args[@]}" --policy "$policy" \
    --inference "$inference" --flow "$flow" --threads 2 --out "build-tsan/out_$policy" >"$log" 2>&1
  rc=$?
  set -e
  if grep -q "unexpected memory mapping\|FATAL: ThreadSanitizer" "$log"; then
    # Older libtsan cannot map its shadow with a high-entropy ASLR layout: retry without ASLR.
    echo "tsan: retrying without address-space randomisation (setarch -R)"
    set +e
    setarch "$(uname -m)" -R build-tsan/src/pcr_orb pipeline --sequence "$drive" \
      "${run_args[@]}" --policy "$policy" --inference "$inference" --flow "$flow" --threads 2 \
      --out "build-tsan/out_$policy" >"$log" 2>&1
    rc=$?
    set -e
  fi
  reports=$(grep -c "WARNING: ThreadSanitizer" "$log" || true)
  suppressed=$(grep -o "ThreadSanitizer: Matched [0-9]* suppressions" "$log" || true)
  if [ "$rc" -eq 0 ] && [ "$reports" -eq 0 ]; then
    echo "tsan: $policy clean (exit 0, no reports${suppressed:+; $suppressed})"
  else
    echo "tsan: $policy NOT clean (exit $rc, $reports reports); first report:"
    sed -n '/WARNING: ThreadSanitizer/,/^=================/p' "$log" | head -60
    status=1
  fi
done
exit $status
