// Map point lookups by id, as tracking and mapping make them (seeded, no data files):
//   BM_PointLookup/N/0   the ordered map (std::map::find; how Map::point looked points up)
//   BM_PointLookup/N/1   the map's point table (Map::point now)
// N live points, made in increasing id order with 40% of them erased again (culled) as a run
// leaves them, then looked up in a random order: a keyframe's keypoints, 1000 at a time.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <random>
#include <vector>

#include "slam/map/map.h"

namespace {

void BM_PointLookup(benchmark::State& state) {
  const int live = static_cast<int>(state.range(0));
  const bool table_lookup = state.range(1) != 0;
  std::mt19937_64 rng(3);
  pcr::PointTable table;
  std::vector<pcr::MapPointId> ids;
  const int made = live * 5 / 3;
  for (int i = 0; i < made; ++i) {
    pcr::MapPoint p;
    p.id = pcr::MapPointId(i);
    p.p_in_world = Eigen::Vector3d(i, 0, 10);
    table.emplace(p.id, std::move(p));
  }
  for (int i = 0; i < made; ++i) {
    if (static_cast<int>(table.size()) > live && rng() % 5 < 2)
      table.erase(pcr::MapPointId(i));
    else
      ids.push_back(pcr::MapPointId(i));
  }
  std::vector<pcr::MapPointId> queries(1000);
  for (pcr::MapPointId& q : queries) q = ids[rng() % ids.size()];
  const auto& ordered = table.all();
  for (auto _ : state) {
    double sum = 0;
    for (const pcr::MapPointId id : queries) {
      const pcr::MapPoint* p = nullptr;
      if (table_lookup) {
        p = table.find(id);
      } else {
        const auto it = ordered.find(id);
        p = it == ordered.end() ? nullptr : &it->second;
      }
      sum += p->p_in_world.x();
    }
    benchmark::DoNotOptimize(sum);
  }
  state.counters["live"] = static_cast<double>(table.size());
  state.counters["slots"] = static_cast<double>(table.index_slots());
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(queries.size()));
}
// Args: live points, lookup (0: the ordered map, 1: the table).
BENCHMARK(BM_PointLookup)
    ->Args({5000, 0})
    ->Args({5000, 1})
    ->Args({20000, 0})
    ->Args({20000, 1})
    ->Args({50000, 0})
    ->Args({50000, 1})
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
