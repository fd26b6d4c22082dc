// Map point lookups by id, as tracking and mapping make them (seeded, no data files):
//   BM_PointLookup/N/0/Q   the ordered map (std::map::find; how Map::point looked points up)
//   BM_PointLookup/N/1/Q   the map's point table (Map::point now)
// N live points, made in increasing id order with 40% of them erased again (culled) as a run
// leaves them, then looked up in a random order. Each lookup reads the found point's position, as
// its callers do, into one of four running sums: the lookups do not wait on each other, so the
// figure is a lookup's cost with lookups overlapping as far as the CPU overlaps them.
//   Q = 1000       hot: a keyframe's keypoints, the same 1000 ids every iteration, so after the
//                  first iteration their index slots, tree nodes and points sit in the cache.
//   Q = 262144     cold: 2^18 random ids an iteration over 1 million live points (~1.7 million
//                  made: some 0.5 GB of tree nodes and a 13 MB index), far more points than the
//                  caches hold, so most lookups wait on memory.
// The per-lookup time is the iteration time over Q (items_per_second is its inverse). The whole
// run takes ~11 s and ~0.6 GB. (benchmark::DoNotOptimize on each lookup's x is no substitute for
// the sums: GCC 12 drops the load of x under it, timing the index alone: 1.3-2 ns cold.)
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <random>
#include <vector>

#include "slam/map/map.h"

namespace {

// The table of `live` points and the ids still in it (built once per size: the cold size takes a
// few seconds and Google Benchmark calls a benchmark several times).
struct Points {
  pcr::PointTable table;
  std::vector<pcr::MapPointId> ids;
};

const Points& PointsOf(int live) {
  static std::map<int, std::unique_ptr<Points>> cache;
  std::unique_ptr<Points>& points = cache[live];
  if (points) return *points;
  points = std::make_unique<Points>();
  std::mt19937_64 rng(3);
  const int made = live * 5 / 3;
  for (int i = 0; i < made; ++i) {
    pcr::MapPoint p;
    p.id = pcr::MapPointId(i);
    p.p_in_world = Eigen::Vector3d(i, 0, 10);
    points->table.emplace(p.id, std::move(p));
  }
  for (int i = 0; i < made; ++i) {
    if (static_cast<int>(points->table.size()) > live && rng() % 5 < 2)
      points->table.erase(pcr::MapPointId(i));
    else
      points->ids.push_back(pcr::MapPointId(i));
  }
  return *points;
}

// Sums the found points' x in four running sums, lookup i into sum i % 4: a lookup's addition does
// not wait on the previous lookup's (one running sum timed its chain of additions, 2-4 cycles a
// lookup, instead of the lookups), and the sums keep the compiler from dropping the lookups.
template <typename Find>
void TimeLookups(benchmark::State& state, const std::vector<pcr::MapPointId>& queries,
                 const Find& find) {
  const size_t n = queries.size() / 4 * 4;
  for (auto _ : state) {
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    for (size_t i = 0; i < n; i += 4) {
      s0 += find(queries[i])->p_in_world.x();
      s1 += find(queries[i + 1])->p_in_world.x();
      s2 += find(queries[i + 2])->p_in_world.x();
      s3 += find(queries[i + 3])->p_in_world.x();
    }
    double sum = (s0 + s1) + (s2 + s3);
    benchmark::DoNotOptimize(sum);
  }
}

void BM_PointLookup(benchmark::State& state) {
  const Points& points = PointsOf(static_cast<int>(state.range(0)));
  const bool table_lookup = state.range(1) != 0;
  std::mt19937_64 rng(4);
  std::vector<pcr::MapPointId> queries(static_cast<size_t>(state.range(2)));  // a multiple of 4
  for (pcr::MapPointId& q : queries) q = points.ids[rng() % points.ids.size()];
  const pcr::PointTable& table = points.table;
  const pcr::PointTable::Points& ordered = table.all();
  if (table_lookup)
    TimeLookups(state, queries, [&table](pcr::MapPointId id) { return table.find(id); });
  else
    TimeLookups(state, queries, [&ordered](pcr::MapPointId id) {
      const auto it = ordered.find(id);
      return it == ordered.end() ? nullptr : &it->second;
    });
  state.counters["live"] = static_cast<double>(table.size());
  state.counters["slots"] = static_cast<double>(table.index_slots());
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(queries.size()));
}
// Args: live points, lookup (0: the ordered map, 1: the table), queries an iteration.
BENCHMARK(BM_PointLookup)
    ->Args({5000, 0, 1000})
    ->Args({5000, 1, 1000})
    ->Args({20000, 0, 1000})
    ->Args({20000, 1, 1000})
    ->Args({50000, 0, 1000})
    ->Args({50000, 1, 1000})
    ->Args({1000000, 0, 1 << 18})
    ->Args({1000000, 1, 1 << 18})
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
