// Exact maximum clique by bitset branch and bound (thesis 4.5 used a heuristic).
#include <binpose/clique.hpp>

#include <algorithm>
#include <cmath>
#include <bit>
#include <numeric>

namespace binpose {
namespace {

using Bits = std::vector<std::uint64_t>;

class Search {
 public:
  Search(const Graph& g, std::uint64_t limit) : g_(g), limit_(limit) {}

  CliqueResult run() {
    Bits all(static_cast<std::size_t>(g_.words()), 0);
    for (int v = 0; v < g_.size(); ++v) all[v / 64] |= 1ull << (v % 64);
    std::vector<int> current;
    expand(current, all);
    CliqueResult r;
    r.vertices = best_;
    std::sort(r.vertices.begin(), r.vertices.end());
    r.exact = !stopped_;
    r.nodes = nodes_;
    return r;
  }

 private:
  /// Greedy sequential colouring of P: vertices in colour order and their colour numbers; a
  /// clique in P has at most as many vertices as colours used up to any vertex.
  void colour(const Bits& P, std::vector<int>& order, std::vector<int>& colours) const {
    Bits uncoloured = P, available(P.size());
    int k = 0;
    while (std::any_of(uncoloured.begin(), uncoloured.end(), [](auto w) { return w != 0; })) {
      ++k;
      available = uncoloured;
      for (std::size_t w = 0; w < available.size(); ++w)
        while (available[w]) {
          const int v = static_cast<int>(w * 64) + std::countr_zero(available[w]);
          available[w] &= available[w] - 1;
          uncoloured[w] &= ~(1ull << (v % 64));
          const std::uint64_t* n = g_.row(v);
          for (std::size_t x = w; x < available.size(); ++x) available[x] &= ~n[x];  // v's neighbours need another colour
          order.push_back(v);
          colours.push_back(k);
        }
    }
  }

  void expand(std::vector<int>& R, Bits P) {
    if (++nodes_ > limit_) { stopped_ = true; return; }
    std::vector<int> order, colours;
    colour(P, order, colours);
    for (int i = static_cast<int>(order.size()) - 1; i >= 0 && !stopped_; --i) {
      if (R.size() + static_cast<std::size_t>(colours[i]) <= best_.size()) return;  // bound
      const int v = order[i];
      R.push_back(v);
      Bits next(P.size());
      bool empty = true;
      const std::uint64_t* n = g_.row(v);
      for (std::size_t w = 0; w < P.size(); ++w) empty &= (next[w] = P[w] & n[w]) == 0;
      if (empty) {
        if (R.size() > best_.size()) best_ = R;
      } else {
        expand(R, std::move(next));
      }
      R.pop_back();
      P[v / 64] &= ~(1ull << (v % 64));
    }
  }

  const Graph& g_;
  std::uint64_t limit_, nodes_ = 0;
  bool stopped_ = false;
  std::vector<int> best_;
};

}  // namespace

int Graph::degree(int v) const {
  int d = 0;
  for (int w = 0; w < words_; ++w) d += std::popcount(row(v)[w]);
  return d;
}

CliqueResult maximumClique(const Graph& g, std::uint64_t work_limit) {
  if (g.size() == 0) return {};
  // Renumber by degree, highest first: tighter colour bounds early (MCQ's initial order).
  std::vector<int> order(static_cast<std::size_t>(g.size()));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return g.degree(a) > g.degree(b); });
  Graph sorted(g.size());
  for (int a = 0; a < g.size(); ++a)
    for (int b = a + 1; b < g.size(); ++b)
      if (g.adjacent(order[a], order[b])) sorted.addEdge(a, b);
  CliqueResult r = Search(sorted, work_limit).run();
  for (int& v : r.vertices) v = order[v];
  std::sort(r.vertices.begin(), r.vertices.end());
  return r;
}

Graph consistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& model, float e_gmax) {
  Graph g(static_cast<int>(cps.size()));
  for (std::size_t i = 0; i < cps.size(); ++i)
    for (std::size_t j = i + 1; j < cps.size(); ++j) {
      const float dm = (model[cps[i].model] - model[cps[j].model]).norm();
      const float ds = (scene[cps[i].scene] - scene[cps[j].scene]).norm();
      if (std::abs(dm - ds) < e_gmax) g.addEdge(static_cast<int>(i), static_cast<int>(j));
    }
  return g;
}

}  // namespace binpose
