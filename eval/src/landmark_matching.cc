#include "landmark_matching.h"

#include <algorithm>
#include <boost/graph/adjacency_list.hpp>
#include <boost/graph/successive_shortest_path_nonnegative_weights.hpp>
#include <cmath>

namespace subslam::eval {
namespace {

// The flow network: source → each estimate → each true landmark within the radius → sink,
// every edge of capacity 1 with its reverse edge of capacity 0 (the residual graph).
// Costs are squared distances in whole units of at least 10⁻⁸ m², held as doubles, the unit
// chosen so that every sum the algorithm forms (a path's cost, at most the vertex count
// times the squared radius) stays an integer below 2⁵⁰: the reduced costs Dijkstra checks
// are then exactly non-negative, and the potentials of vertices the residual graph no
// longer reaches grow to +∞ (floating point) instead of overflowing an integer.
using Traits = boost::adjacency_list_traits<boost::vecS, boost::vecS, boost::directedS>;
using Network = boost::adjacency_list<
    boost::vecS, boost::vecS, boost::directedS, boost::no_property,
    boost::property<boost::edge_capacity_t, long,
                    boost::property<boost::edge_residual_capacity_t, long,
                                    boost::property<boost::edge_reverse_t, Traits::edge_descriptor,
                                                    boost::property<boost::edge_weight_t, double>>>>>;

}  // namespace

LandmarkMatching MatchWithinRadius(const std::vector<Eigen::Vector2d>& estimates,
                                   const std::vector<Eigen::Vector2d>& truth, double radius_m) {
  const int n = static_cast<int>(estimates.size()), m = static_cast<int>(truth.size());
  const int source = n + m, sink = n + m + 1;
  Network g(n + m + 2);
  const double cost_per_square_metre =
      std::min(1e8, std::ldexp(1.0, 50) / ((n + m + 2) * std::max(radius_m * radius_m, 1e-300)));
  auto capacity = boost::get(boost::edge_capacity, g);
  auto reverse = boost::get(boost::edge_reverse, g);
  auto weight = boost::get(boost::edge_weight, g);
  const auto add = [&](int u, int v, double cost) {
    const Traits::edge_descriptor e = boost::add_edge(u, v, g).first;
    const Traits::edge_descriptor r = boost::add_edge(v, u, g).first;
    capacity[e] = 1;
    capacity[r] = 0;
    weight[e] = cost;
    weight[r] = -cost;
    reverse[e] = r;
    reverse[r] = e;
  };
  // Pairs within the radius, found over the truth sorted by x.
  std::vector<int> by_x(m);
  for (int j = 0; j < m; ++j) by_x[j] = j;
  std::sort(by_x.begin(), by_x.end(), [&](int a, int b) { return truth[a].x() < truth[b].x(); });
  std::vector<char> has_pair(m, 0);
  LandmarkMatching out;
  out.near_truth.assign(n, 0);
  bool any_pair = false;
  for (int i = 0; i < n; ++i) {
    const auto first = std::lower_bound(by_x.begin(), by_x.end(), estimates[i].x() - radius_m,
                                        [&](int j, double x) { return truth[j].x() < x; });
    bool any = false;
    for (auto it = first; it != by_x.end() && truth[*it].x() <= estimates[i].x() + radius_m; ++it) {
      const double d2 = (estimates[i] - truth[*it]).squaredNorm();
      if (!(d2 <= radius_m * radius_m)) continue;
      add(i, n + *it, std::round(d2 * cost_per_square_metre));
      has_pair[*it] = 1;
      any = true;
    }
    if (any) add(source, i, 0);
    out.near_truth[i] = any ? 1 : 0;
    any_pair = any_pair || any;
  }
  for (int j = 0; j < m; ++j) {
    if (has_pair[j]) add(n + j, sink, 0);
  }
  if (!any_pair) return out;
  boost::successive_shortest_path_nonnegative_weights(g, source, sink);
  auto residual = boost::get(boost::edge_residual_capacity, g);
  for (int i = 0; i < n; ++i) {
    for (const auto& e : boost::make_iterator_range(boost::out_edges(i, g))) {
      const int v = static_cast<int>(boost::target(e, g));
      if (v >= n && v < n + m && capacity[e] == 1 && residual[e] == 0) out.pairs.push_back({i, v - n});
    }
  }
  return out;
}

}  // namespace subslam::eval
