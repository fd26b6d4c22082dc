# Precompiled headers shared between targets (PCR_PRECOMPILED_HEADERS).
#
# Every unity batch of every target used to parse the same third-party headers again (6-10 s a
# batch for the standard library, Eigen, OpenCV's core, fmt and spdlog, GoogleTest in the tests).
# They are precompiled once for each of the three ways the project compiles C++, and the targets
# reuse that header (REUSE_FROM):
#   library     position-independent code: the layers' static libraries (they are linked into
#               libpcr_orb.so as well);
#   executable  pcr_orb, its command-line library and the benchmarks;
#   test        the GoogleTest executables and their support library (GoogleTest's header too).
# GCC takes a precompiled header only when it was made with the same code-generation options
# (-fPIC against the default -fPIE) and the same definitions of the macros it tests
# (GTEST_HAS_PTHREAD, _OPENMP), hence three, and none for pcr_gpu (OpenMP). Sources still
# include what they use: the precompiled headers only make the build faster.
set(PCR_PCH_HEADERS
    <algorithm> <array> <atomic> <chrono> <cmath> <cstddef> <cstdint> <cstdio> <cstring>
    <filesystem> <fstream> <functional> <limits> <map> <memory> <mutex> <numeric> <optional>
    <set> <sstream> <stdexcept> <string> <string_view> <unordered_map> <utility> <vector>
    <Eigen/Core> <Eigen/Geometry> <opencv2/core.hpp> <opencv2/imgproc.hpp> <fmt/format.h>
    <spdlog/spdlog.h>)

# pcr_pch_origin(KIND PIC LIBS... [HEADERS ...]): the target pcr_pch_KIND that builds KIND's
# precompiled header from PCR_PCH_HEADERS and the extra HEADERS, with LIBS' usage requirements.
function(pcr_pch_origin kind pic)
  cmake_parse_arguments(PARSE_ARGV 2 arg "" "" "LIBS;HEADERS")
  add_library(pcr_pch_${kind} OBJECT ${CMAKE_SOURCE_DIR}/cmake/pch_origin.cpp)
  set_target_properties(pcr_pch_${kind} PROPERTIES POSITION_INDEPENDENT_CODE ${pic}
                                                   UNITY_BUILD OFF)
  target_link_libraries(pcr_pch_${kind} PRIVATE ${arg_LIBS})
  target_precompile_headers(pcr_pch_${kind} PRIVATE ${PCR_PCH_HEADERS} ${arg_HEADERS})
endfunction()

# GCC only: GCC skips a precompiled header that does not fit a target (falling back to the
# headers themselves), while Clang (the fuzz preset) refuses one made with other -D options.
set(PCR_USE_PCH OFF)
if(PCR_PRECOMPILED_HEADERS AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  set(PCR_USE_PCH ON)
endif()

if(PCR_USE_PCH)
  set(pch_libs Eigen3::Eigen ${OpenCV_LIBS} spdlog::spdlog fmt::fmt)
  pcr_pch_origin(library ON LIBS ${pch_libs})
  pcr_pch_origin(executable OFF LIBS ${pch_libs})
  if(PCR_BUILD_TESTS)
    find_package(GTest REQUIRED)
    pcr_pch_origin(test OFF LIBS ${pch_libs} GTest::gtest HEADERS <gtest/gtest.h>)
  endif()
endif()

# pcr_precompiled_headers(TARGET library|executable|test): TARGET's C++ sources reuse the
# precompiled header of that kind (nothing when PCR_USE_PCH is off).
function(pcr_precompiled_headers target kind)
  if(NOT kind MATCHES "^(library|executable|test)$")
    message(FATAL_ERROR "pcr_precompiled_headers: kind must be library, executable or test")
  endif()
  if(PCR_USE_PCH)
    target_precompile_headers(${target} REUSE_FROM pcr_pch_${kind})
  endif()
endfunction()
