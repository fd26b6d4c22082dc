#!/usr/bin/env bash
# Fails when a layer includes what ../shared/ARCHITECTURE.md forbids it:
#  - src/slam and src/nodes: no TBB, CUDA or YAML headers;
#  - src/slam: nothing from nodes, graph, gpu, app, io, eval or sim;
#  - io, eval, sim: only slam/common from the slam layer, nothing from nodes/graph/app;
#  - only src/graph includes the TBB flow graph;
#  - src/driver (the frame path and the public API) and src/app sit on top: nothing below them
#    includes them, the driver not the app, and include/pcr/*.h nothing internal;
#  - src/gpu builds on src/slam only, and CUDA headers (and the project's .cuh headers, which
#    include them) appear in src/gpu/*.cu files only.
set -u
root=${1:-.}
cd "$root" || exit 2
fail=0
report() { echo "layering: $1"; echo "$2" | sed 's/^/  /'; fail=1; }
hits=$(grep -rnE '#include *[<"](oneapi/tbb|tbb/|cuda|yaml-cpp)' src/slam src/nodes 2>/dev/null)
[ -n "$hits" ] && report "TBB/CUDA/YAML header below src/graph" "$hits"
hits=$(grep -rnE '#include *"(nodes|graph|gpu|app|io|eval|sim)/' src/slam 2>/dev/null)
[ -n "$hits" ] && report "src/slam includes a layer above it" "$hits"
hits=$(grep -rnE '#include *"(slam/(features|map|tracking|mapping|optim|dynamic|loop|geometry)|nodes|graph|app)/' src/io src/eval src/sim 2>/dev/null)
[ -n "$hits" ] && report "io/eval/sim reach beyond slam/common" "$hits"
hits=$(grep -rlE '#include *[<"]oneapi/tbb/flow_graph' src | grep -v '^src/graph/')
[ -n "$hits" ] && report "flow graph included outside src/graph" "$hits"
hits=$(grep -rnE '\b(std::thread|usleep|sleep_for)\b' src/slam 2>/dev/null)
[ -n "$hits" ] && report "threads or sleeps in src/slam" "$hits"
hits=$(grep -rnE '#include *"(nodes|graph|app|io|eval|sim)/' src/gpu 2>/dev/null)
[ -n "$hits" ] && report "src/gpu reaches above src/slam" "$hits"
hits=$(grep -rnE '#include *[<"](cuda|cublas|cudnn)' src --include='*.h' --include='*.cpp' 2>/dev/null)
[ -n "$hits" ] && report "CUDA header outside a .cu file" "$hits"
hits=$(grep -rnE '#include *[<"][^">]*\.cuh[">]' src --include='*.h' --include='*.cpp' 2>/dev/null)
[ -n "$hits" ] && report "CUDA-only header (.cuh) outside a .cu file" "$hits"
hits=$(find src -name '*.cu' -not -path 'src/gpu/*')
[ -n "$hits" ] && report ".cu file outside src/gpu" "$hits"
hits=$(grep -rnE '#include *"(driver|app)/' src/slam src/nodes src/graph src/gpu src/io src/eval src/sim 2>/dev/null)
[ -n "$hits" ] && report "a layer below src/driver includes the driver or the app" "$hits"
hits=$(grep -rnE '#include *"app/' src/driver 2>/dev/null)
[ -n "$hits" ] && report "src/driver includes the app" "$hits"
hits=$(grep -nE '#include *"' include/pcr/*.h | grep -vE '#include *"pcr/')
[ -n "$hits" ] && report "the public headers include internal headers" "$hits"
if [ $fail -eq 0 ]; then echo "layering: ok"; fi
exit $fail
