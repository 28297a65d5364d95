// Exact maximum clique by bitset branch and bound (thesis 4.5 used a heuristic).
#include <binpose/clique.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <bit>
#include <numeric>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace binpose {
namespace {

using Bits = std::vector<std::uint64_t>;

class Search {
 public:
  /// `floor`: a clique of that many vertices is known already; only larger ones are searched.
  Search(const Graph& g, std::uint64_t limit, std::size_t floor) : g_(g), limit_(limit), floor_(floor) {}

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
      if (R.size() + static_cast<std::size_t>(colours[i]) <= std::max(best_.size(), floor_)) return;  // bound
      const int v = order[i];
      R.push_back(v);
      Bits next(P.size());
      bool empty = true;
      const std::uint64_t* n = g_.row(v);
      for (std::size_t w = 0; w < P.size(); ++w) empty &= (next[w] = P[w] & n[w]) == 0;
      if (empty) {
        if (R.size() > std::max(best_.size(), floor_)) best_ = R;
      } else {
        expand(R, std::move(next));
      }
      R.pop_back();
      P[v / 64] &= ~(1ull << (v % 64));
    }
  }

  const Graph& g_;
  std::uint64_t limit_, nodes_ = 0;
  std::size_t floor_;
  bool stopped_ = false;
  std::vector<int> best_;
};

/// A clique grown greedily from each of the few highest-degree vertices (adding, in degree
/// order, every vertex adjacent to all chosen so far); the largest of them. A lower bound.
std::vector<int> greedyClique(const Graph& g, const std::vector<int>& by_degree) {
  constexpr int kStarts = 4;
  std::vector<int> best, clique;
  Bits P(static_cast<std::size_t>(g.words()));
  for (int s = 0; s < std::min<int>(kStarts, static_cast<int>(by_degree.size())); ++s) {
    const int start = by_degree[s];
    clique.assign(1, start);
    std::copy(g.row(start), g.row(start) + g.words(), P.begin());
    for (const int v : by_degree) {
      if (!((P[v / 64] >> (v % 64)) & 1ull)) continue;
      clique.push_back(v);
      const std::uint64_t* n = g.row(v);
      for (std::size_t w = 0; w < P.size(); ++w) P[w] &= n[w];
    }
    if (clique.size() > best.size()) best = clique;
  }
  return best;
}

/// Marks the vertices left after repeatedly removing those with fewer than `k` remaining
/// neighbours (the k-core): every clique of more than k vertices lies in it.
std::vector<char> coreOf(const Graph& g, std::vector<int> degree, int k) {
  const int n = g.size();
  std::vector<char> in_core(static_cast<std::size_t>(n), 1);
  std::vector<int> queue;
  for (int v = 0; v < n; ++v)
    if (degree[v] < k) { in_core[v] = 0; queue.push_back(v); }
  while (!queue.empty()) {
    const int v = queue.back();
    queue.pop_back();
    const std::uint64_t* row = g.row(v);
    for (int w = 0; w < g.words(); ++w)
      for (std::uint64_t bits = row[w]; bits; bits &= bits - 1) {
        const int u = w * 64 + std::countr_zero(bits);
        if (in_core[u] && --degree[u] < k) { in_core[u] = 0; queue.push_back(u); }
      }
  }
  return in_core;
}

/// Row i of the consistency graph (eq. 13-16) from word `first` on, 64 partners to a word.
/// Built for AVX2 as well as the baseline, the better one chosen at run time; no FMA, so every
/// build computes the same bits.
__attribute__((target_clones("avx2", "default")))
void linkRow(const std::array<const float*, 6>& c, int i, int n, int first, float e_gmax, std::uint64_t* row) {
  alignas(64) std::array<std::uint8_t, 64> linked{};
  for (int w0 = first * 64; w0 < n; w0 += 64) {
    const int count = std::min(64, n - w0);
    for (int b = 0; b < count; ++b) {
      const int j = w0 + b;
      const float sx = c[0][j] - c[0][i], sy = c[1][j] - c[1][i], sz = c[2][j] - c[2][i];
      const float mx = c[3][j] - c[3][i], my = c[4][j] - c[4][i], mz = c[5][j] - c[5][i];
      const float ds = std::sqrt(sx * sx + sy * sy + sz * sz), dm = std::sqrt(mx * mx + my * my + mz * mz);
      linked[b] = std::abs(dm - ds) < e_gmax;
    }
    std::uint64_t word = 0;
    for (int b = 0; b < count; ++b) word |= std::uint64_t{linked[b]} << b;
    row[w0 / 64] = word;
  }
}

/// In-place transpose of a 64 x 64 bit block (bit c of a[r] <-> bit r of a[c]), by swapping
/// ever smaller sub-blocks (Warren, Hacker's Delight 7-3).
void transpose64(std::array<std::uint64_t, 64>& a) {
  std::uint64_t m = 0x00000000FFFFFFFFull;
  for (int j = 32; j != 0; j >>= 1, m ^= m << j)
    for (int k = 0; k < 64; k = ((k | j) + 1) & ~j) {
      const std::uint64_t t = ((a[k] >> j) ^ a[k | j]) & m;
      a[k] ^= t << j;
      a[k | j] ^= t;
    }
}

}  // namespace

int Graph::degree(int v) const {
  int d = 0;
  for (int w = 0; w < words_; ++w) d += std::popcount(row(v)[w]);
  return d;
}

CliqueResult maximumClique(const Graph& g, std::uint64_t work_limit) {
  if (g.size() == 0) return {};
  const int n = g.size();
  std::vector<int> degree(static_cast<std::size_t>(n));
  for (int v = 0; v < n; ++v) degree[v] = g.degree(v);
  std::vector<int> by_degree(static_cast<std::size_t>(n));
  std::iota(by_degree.begin(), by_degree.end(), 0);
  std::stable_sort(by_degree.begin(), by_degree.end(), [&](int a, int b) { return degree[a] > degree[b]; });
  const std::vector<int> greedy = greedyClique(g, by_degree);
  // Only vertices of at least |greedy| neighbours among themselves can lie in a larger clique;
  // they keep the degree order, highest first: tighter colour bounds early (MCQ's initial order).
  const std::vector<char> in_core = coreOf(g, degree, static_cast<int>(greedy.size()));
  std::vector<int> order;
  for (const int v : by_degree)
    if (in_core[v]) order.push_back(v);
  CliqueResult r;
  r.vertices = greedy;
  if (order.size() > greedy.size()) {
    const int m = static_cast<int>(order.size());
    std::vector<int> position(static_cast<std::size_t>(n), -1);
    for (int a = 0; a < m; ++a) position[order[a]] = a;
    Graph sorted(m);
    for (int a = 0; a < m; ++a) {  // each row's bits moved to their new places
      std::uint64_t* to = sorted.mutableRow(a);
      const std::uint64_t* from = g.row(order[a]);
      for (int w = 0; w < g.words(); ++w)
        for (std::uint64_t bits = from[w]; bits; bits &= bits - 1)
          if (const int b = position[w * 64 + std::countr_zero(bits)]; b >= 0) to[b / 64] |= 1ull << (b % 64);
    }
    CliqueResult found = Search(sorted, work_limit, greedy.size()).run();
    r.exact = found.exact;
    r.nodes = found.nodes;
    if (found.vertices.size() > greedy.size()) {
      r.vertices.clear();
      for (const int v : found.vertices) r.vertices.push_back(order[v]);
    }
  }
  std::sort(r.vertices.begin(), r.vertices.end());
  return r;
}

Graph consistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& model, float e_gmax) {
  const int n = static_cast<int>(cps.size());
  Graph g(n);
  // Coordinates side by side, so the inner loop runs on SIMD lanes. Row i is computed from its
  // diagonal word on (the 64 x 64 blocks on and above the diagonal); the blocks below are those
  // above, bit-transposed. The two distances are bitwise equal either way round, so this is the
  // graph of every (i, j) computed in full.
  std::array<std::vector<float>, 6> c;
  for (auto& v : c) v.resize(cps.size());
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      c[k][i] = scene[cps[i].scene][k];
      c[3 + k][i] = model[cps[i].model][k];
    }
  const std::array<const float*, 6> coords{c[0].data(), c[1].data(), c[2].data(), c[3].data(), c[4].data(), c[5].data()};
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 32), [&](const tbb::blocked_range<int>& rows) {  // rows apart
    for (int i = rows.begin(); i < rows.end(); ++i) {
      std::uint64_t* row = g.mutableRow(i);
      linkRow(coords, i, n, i / 64, e_gmax, row);
      row[i / 64] &= ~(1ull << (i % 64));
    }
  });
  const int blocks = g.words();
  tbb::parallel_for(1, blocks, [&](int J) {  // block J's rows, words 0..J-1, from blocks (I, J) above
    std::array<std::uint64_t, 64> a;
    for (int I = 0; I < J; ++I) {
      for (int r = 0; r < 64; ++r) a[r] = I * 64 + r < n ? g.row(I * 64 + r)[J] : 0;
      transpose64(a);
      for (int r = 0; r < 64 && J * 64 + r < n; ++r) g.mutableRow(J * 64 + r)[I] = a[r];
    }
  });
  return g;
}

}  // namespace binpose
