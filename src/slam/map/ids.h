#pragma once
// Strong ids for keyframes and map points: distinct types so that one cannot be passed for the
// other. An id is valid when its value is >= 0. Ordered and hashable, so they key std::map and
// std::unordered_map; iteration over ordered containers is deterministic.
#include <cstddef>
#include <cstdint>
#include <functional>

namespace pcr {

template <typename Tag>
struct StrongId {
  int64_t value = -1;

  constexpr StrongId() = default;
  constexpr explicit StrongId(int64_t v) : value(v) {}
  constexpr bool valid() const { return value >= 0; }
  constexpr auto operator<=>(const StrongId&) const = default;
};

// A keyframe's id is the id of the frame it was made from (unique per frame, known before the
// map assigns anything).
using KeyframeId = StrongId<struct KeyframeIdTag>;
// Map point ids are assigned by the map, in increasing order, when a delta is applied.
using MapPointId = StrongId<struct MapPointIdTag>;

}  // namespace pcr

template <typename Tag>
struct std::hash<pcr::StrongId<Tag>> {
  size_t operator()(const pcr::StrongId<Tag>& id) const noexcept {
    return std::hash<int64_t>()(id.value);
  }
};
