// Exact maximum clique by bitset branch and bound (thesis 4.5 used a heuristic).
#include <binpose/clique.hpp>

#include "graph_workspace.hpp"
#include "simd.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <bit>
#include <cstring>
#include <deque>
#include <numbers>
#include <optional>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace binpose {
namespace {

using Bits = std::vector<std::uint64_t>;

/// One depth of the search: its candidate set P and the colouring's buffers, kept from one
/// node to the next (no allocation per node once the depth has been reached).
struct Level {
  Bits P, uncoloured, available;
  std::vector<int> order, colours;
};

class Search {
 public:
  /// `floor`: a clique of that many vertices is known already; only larger ones are searched.
  /// `levels`: the depths' buffers, kept by the caller from one search to the next.
  Search(const Graph& g, std::uint64_t limit, std::size_t floor, std::deque<Level>& levels)
      : g_(g), limit_(limit), floor_(floor), levels_(levels) {}

  CliqueResult run() {
    Bits& all = level(0).P;
    all.assign(static_cast<std::size_t>(g_.words()), 0);
    for (int v = 0; v < g_.size(); ++v) all[v / 64] |= 1ull << (v % 64);
    std::vector<int> current;
    expand(current, 0);
    CliqueResult r;
    r.vertices = best_;
    std::sort(r.vertices.begin(), r.vertices.end());
    r.exact = !stopped_;
    r.nodes = nodes_;
    return r;
  }

 private:
  /// The buffers of depth d (a deque: the levels above keep their places as it grows).
  Level& level(std::size_t d) {
    while (levels_.size() <= d) levels_.emplace_back();
    return levels_[d];
  }

  /// Greedy sequential colouring of L.P: vertices in colour order and their colour numbers; a
  /// clique in P has at most as many vertices as colours used up to any vertex.
  void colour(Level& L) const {
    L.order.clear();
    L.colours.clear();
    L.uncoloured = L.P;
    int k = 0;
    while (std::any_of(L.uncoloured.begin(), L.uncoloured.end(), [](auto w) { return w != 0; })) {
      ++k;
      L.available = L.uncoloured;
      for (std::size_t w = 0; w < L.available.size(); ++w)
        while (L.available[w]) {
          const int v = static_cast<int>(w * 64) + std::countr_zero(L.available[w]);
          L.available[w] &= L.available[w] - 1;
          L.uncoloured[w] &= ~(1ull << (v % 64));
          const std::uint64_t* n = g_.row(v);
          for (std::size_t x = w; x < L.available.size(); ++x) L.available[x] &= ~n[x];  // v's neighbours need another colour
          L.order.push_back(v);
          L.colours.push_back(k);
        }
    }
  }

  /// Searches the cliques R + (some of level(depth).P).
  void expand(std::vector<int>& R, std::size_t depth) {
    if (++nodes_ > limit_) { stopped_ = true; return; }
    Level& L = level(depth);
    colour(L);
    for (int i = static_cast<int>(L.order.size()) - 1; i >= 0 && !stopped_; --i) {
      if (R.size() + static_cast<std::size_t>(L.colours[i]) <= std::max(best_.size(), floor_)) return;  // bound
      const int v = L.order[i];
      R.push_back(v);
      Bits& next = level(depth + 1).P;
      next.resize(L.P.size());
      bool empty = true;
      const std::uint64_t* n = g_.row(v);
      for (std::size_t w = 0; w < L.P.size(); ++w) empty &= (next[w] = L.P[w] & n[w]) == 0;
      if (empty) {
        if (R.size() > std::max(best_.size(), floor_)) best_ = R;
      } else {
        expand(R, depth + 1);
      }
      R.pop_back();
      L.P[v / 64] &= ~(1ull << (v % 64));
    }
  }

  const Graph& g_;
  std::uint64_t limit_, nodes_ = 0;
  std::size_t floor_;
  bool stopped_ = false;
  std::vector<int> best_;
  std::deque<Level>& levels_;
};

/// A clique grown greedily from each of the few highest-degree vertices (adding, in degree
/// order, every vertex adjacent to all chosen so far); the largest of them, into `best`. A
/// lower bound. `clique` and `P`: buffers.
void greedyClique(const Graph& g, const std::vector<int>& by_degree, std::vector<int>& best, std::vector<int>& clique, Bits& P) {
  constexpr int kStarts = 4;
  best.clear();
  P.resize(static_cast<std::size_t>(g.words()));
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
}

/// Marks in `in_core` the vertices left after repeatedly removing those with fewer than `k`
/// remaining neighbours (the k-core): every clique of more than k vertices lies in it.
/// `degree` is used up; `queue`: a buffer.
void coreOf(const Graph& g, std::vector<int>& degree, int k, std::vector<char>& in_core, std::vector<int>& queue) {
  const int n = g.size();
  in_core.assign(static_cast<std::size_t>(n), 1);
  queue.clear();
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
}

/// Squared model distances d_m^2 that eq. 15-16 accept against a scene distance d_s: those with
/// |d_m - d_s| < e_gmax, that is (d_s - e_gmax)^2 < d_m^2 < (d_s + e_gmax)^2 (no lower bound
/// when d_s <= e_gmax).
struct Band {
  float low2, high2;
};

Band bandOf(float ds, float e_gmax) {
  const float low = ds - e_gmax;
  return {low > 0 ? low * low : -1.0f, (ds + e_gmax) * (ds + e_gmax)};
}

struct CosineBand {
  float low, high;
};

/// The cosines a model pair's normals may have when its scene normals' cosine is `cs`: their
/// angles differ by at most `tolerance` radians. A band reaching 0 or pi is open at that end
/// (a cosine rounded past +-1 stays in).
CosineBand cosineBandOf(float cs, float tolerance) {
  constexpr float kPi = std::numbers::pi_v<float>;
  constexpr float kOpen = 2.0f;
  const float angle = std::acos(std::clamp(cs, -1.0f, 1.0f));
  return {angle + tolerance >= kPi ? -kOpen : std::cos(angle + tolerance), angle <= tolerance ? kOpen : std::cos(angle - tolerance)};
}

/// A row's bands, one per column: of squared model distances (eq. 13-16) and, for the test of
/// normals, of the model normals' cosines.
struct Bands {
  std::vector<float> low2, high2, cos_low, cos_high;
};

/// The model's coordinates (and normals) side by side, so the inner loop runs on SIMD lanes.
struct Columns {
  std::array<const float*, 3> points;
  std::array<const float*, 3> normals;  ///< null: no test of normals
};

/// The correspondences' model points (and normals) as columns, in `storage`.
Columns columnsOf(std::span<const Correspondence> cps, const Points& model, const Points* model_normals,
                  std::array<std::vector<float>, 6>& storage) {
  const int used = model_normals != nullptr ? 6 : 3;  // the points' columns, then the normals'
  for (int k = 0; k < used; ++k) storage[k].resize(cps.size());
  for (std::size_t i = 0; i < cps.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      storage[k][i] = model[cps[i].model][k];
      if (model_normals != nullptr) storage[3 + k][i] = (*model_normals)[cps[i].model][k];
    }
  Columns c{{storage[0].data(), storage[1].data(), storage[2].data()}, {nullptr, nullptr, nullptr}};
  if (model_normals != nullptr) c.normals = {storage[3].data(), storage[4].data(), storage[5].data()};
  return c;
}

/// Row i of the consistency graph (eq. 13-16) from word `first` on, 64 partners to a word:
/// j is linked when its squared model distance to i lies in the band of their scene distance
/// and, with normals, the cosine of their model normals in the band of their scene normals'.
/// Built for AVX2 as well as the baseline, the better one chosen at run time; no FMA, so every
/// build computes the same bits.
__attribute__((target_clones("avx2", "default")))
void linkRow(const Columns& m, const Bands& band, int i, int n, int first, std::uint64_t* row) {
  alignas(64) std::array<std::uint8_t, 64> linked{};
  const auto& [px, py, pz] = m.points;
  const float x = px[i], y = py[i], z = pz[i];
  const bool angles = m.normals[0] != nullptr;
  const float nx = angles ? m.normals[0][i] : 0, ny = angles ? m.normals[1][i] : 0, nz = angles ? m.normals[2][i] : 0;
  for (int w0 = first * 64; w0 < n; w0 += 64) {
    const int count = std::min(64, n - w0);
    for (int b = 0; b < count; ++b) {
      const int j = w0 + b;
      const float mx = px[j] - x, my = py[j] - y, mz = pz[j] - z;
      const float dm2 = mx * mx + my * my + mz * mz;
      linked[b] = (dm2 > band.low2[j]) & (dm2 < band.high2[j]);
    }
    if (angles)
      for (int b = 0; b < count; ++b) {
        const int j = w0 + b;
        const float c = m.normals[0][j] * nx + m.normals[1][j] * ny + m.normals[2][j] * nz;
        linked[b] = static_cast<std::uint8_t>(linked[b] & (c >= band.cos_low[j]) & (c <= band.cos_high[j]));
      }
    // Eight 0/1 bytes to eight bits by one multiply (each byte's bit lands in the top byte,
    // on its own place; no two partial products meet): a byte at a time cost twice the tests.
    std::uint64_t word = 0;
    for (int g = 0; g < 8; ++g) {
      std::uint64_t eight;
      std::memcpy(&eight, linked.data() + 8 * g, sizeof eight);
      word |= ((eight * 0x0102040810204080ull) >> 56) << (8 * g);
    }
    row[w0 / 64] = count == 64 ? word : word & ((1ull << count) - 1);  // bytes past count are stale
  }
}

/// In-place transpose of a 64 x 64 bit block (bit c of a[r] <-> bit r of a[c]), by swapping
/// ever smaller sub-blocks (Warren, Hacker's Delight 7-3).
void transpose64Scalar(std::array<std::uint64_t, 64>& a) {
  std::uint64_t m = 0x00000000FFFFFFFFull;
  for (int j = 32; j != 0; j >>= 1, m ^= m << j)
    for (int k = 0; k < 64; k = ((k | j) + 1) & ~j) {
      const std::uint64_t t = ((a[k] >> j) ^ a[k | j]) & m;
      a[k] ^= t << j;
      a[k | j] ^= t;
    }
}

#if defined(__x86_64__)
/// Rows k and k + j of the 16 registers swapped in their j x j sub-blocks (j = 32, 16, 8, 4).
BINPOSE_AVX2_INLINE void swapRegisters(__m256i (&v)[16], int j, std::uint64_t mask) {
  const __m256i m = _mm256_set1_epi64x(static_cast<long long>(mask));
  const __m128i shift = _mm_cvtsi32_si128(j);
  const int apart = j / 4;
  for (int q = 0; q < 16; ++q) {
    if (q & apart) continue;
    const __m256i t = _mm256_and_si256(_mm256_xor_si256(_mm256_srl_epi64(v[q], shift), v[q + apart]), m);
    v[q] = _mm256_xor_si256(v[q], _mm256_sll_epi64(t, shift));
    v[q + apart] = _mm256_xor_si256(v[q + apart], t);
  }
}

/// The same swaps, four rows to a 256-bit register, all 64 rows in 16 registers: the swaps of
/// rows 4 and more apart pair whole registers, those of rows 2 and 1 apart pair lanes of one
/// (a lane permute, then a blend). The scalar loop kept its rows in memory, each swap waiting on
/// the store before it: perf put its xor and stores at 57% of maximumClique's own time.
__attribute__((target("avx2"))) void transpose64Avx2(std::array<std::uint64_t, 64>& a) {
  __m256i v[16];
  for (int q = 0; q < 16; ++q) v[q] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a.data() + 4 * q));
  swapRegisters(v, 32, 0x00000000FFFFFFFFull);
  swapRegisters(v, 16, 0x0000FFFF0000FFFFull);
  swapRegisters(v, 8, 0x00FF00FF00FF00FFull);
  swapRegisters(v, 4, 0x0F0F0F0F0F0F0F0Full);
  const __m256i m2 = _mm256_set1_epi64x(0x3333333333333333ll), m1 = _mm256_set1_epi64x(0x5555555555555555ll);
  for (int q = 0; q < 16; ++q) {
    // Rows 2 apart: lanes (0, 2) and (1, 3). t in lanes 0 and 1, moved to lanes 2 and 3.
    __m256i t = _mm256_and_si256(_mm256_xor_si256(_mm256_srli_epi64(v[q], 2), _mm256_permute4x64_epi64(v[q], 0x4E)), m2);
    v[q] = _mm256_xor_si256(v[q], _mm256_blend_epi32(_mm256_slli_epi64(t, 2), _mm256_permute4x64_epi64(t, 0x4E), 0xF0));
    // Rows 1 apart: lanes (0, 1) and (2, 3). t in lanes 0 and 2, moved to lanes 1 and 3.
    t = _mm256_and_si256(_mm256_xor_si256(_mm256_srli_epi64(v[q], 1), _mm256_shuffle_epi32(v[q], 0x4E)), m1);
    v[q] = _mm256_xor_si256(v[q], _mm256_blend_epi32(_mm256_slli_epi64(t, 1), _mm256_shuffle_epi32(t, 0x4E), 0xCC));
  }
  for (int q = 0; q < 16; ++q) _mm256_storeu_si256(reinterpret_cast<__m256i*>(a.data() + 4 * q), v[q]);
}
#endif

/// The subgraph of the vertices `order` (a symmetric graph's), vertex a of it being order[a]:
/// P g P^T for the permutation P that picks them. X = P g picks rows; X^T = g P^T (g is
/// symmetric) is one bit transpose, 64 x 64 blocks at a time; P X^T picks its rows again. A
/// scatter of each edge's bit to its new place cost as much as building the graph (ipd0-32).
/// Into `sorted`, with `xt` a buffer.
void relabelled(const Graph& g, const std::vector<int>& order, Graph& sorted, std::vector<std::uint64_t>& xt) {
  const int m = static_cast<int>(order.size());
  sorted.reset(m);
  const int xw = g.words(), yw = sorted.words();  // words of a row of X (g's columns), of X^T (m columns)
  xt.assign(static_cast<std::size_t>(xw) * 64 * yw, 0);  // X^T, g's columns rounded up to 64
  std::array<std::uint64_t, 64> block;
  for (int I = 0; I < yw; ++I)    // X's rows 64 I ..
    for (int J = 0; J < xw; ++J) {  // .. and columns 64 J ..
      std::uint64_t any = 0;
      for (int r = 0; r < 64; ++r) any |= block[r] = 64 * I + r < m ? g.row(order[64 * I + r])[J] : 0;
      if (any == 0) continue;
      transposeBits64(block);  // block[c] bit r: X's row 64 I + r, column 64 J + c
      for (int c = 0; c < 64; ++c) xt[static_cast<std::size_t>(64 * J + c) * yw + I] = block[c];
    }
  for (int a = 0; a < m; ++a)
    std::copy_n(xt.begin() + static_cast<std::ptrdiff_t>(order[a]) * yw, yw, sorted.mutableRow(a));
}

}  // namespace

void transposeBits64(std::array<std::uint64_t, 64>& a, bool simd) {
#if defined(__x86_64__)
  if (simd && detail::haveAvx2()) return transpose64Avx2(a);
#endif
  transpose64Scalar(a);
}

int Graph::degree(int v) const {
  int d = 0;
  for (int w = 0; w < words_; ++w) d += std::popcount(row(v)[w]);
  return d;
}

void Graph::isolate(std::span<const int> vertices) {
  for (const int v : vertices) {
    std::uint64_t* row = mutableRow(v);
    for (int w = 0; w < words_; ++w)
      for (std::uint64_t bits = row[w]; bits; bits &= bits - 1) {
        const int u = w * 64 + std::countr_zero(bits);
        mutableRow(u)[v / 64] &= ~(1ull << (v % 64));
      }
    std::fill_n(row, words_, std::uint64_t{0});
  }
}

void Graph::mirrorUpper() {
  tbb::parallel_for(0, words_, [&](int J) {  // block J's rows: words 0..J-1 from blocks (I, J) above, then word J
    std::array<std::uint64_t, 64> a;
    for (int I = 0; I < J; ++I) {
      for (int r = 0; r < 64; ++r) a[r] = I * 64 + r < n_ ? row(I * 64 + r)[J] : 0;
      transposeBits64(a);
      for (int r = 0; r < 64 && J * 64 + r < n_; ++r) mutableRow(J * 64 + r)[I] = a[r];
    }
    for (int r = 0; r < 64; ++r) a[r] = J * 64 + r < n_ ? row(J * 64 + r)[J] : 0;
    transposeBits64(a);
    for (int r = 0; r < 64 && J * 64 + r < n_; ++r) mutableRow(J * 64 + r)[J] |= a[r];
  });
}

/// maximumClique's buffers: the caller keeps them from one call to the next (a matcher made
/// hundreds of calls a scan, each allocating about fifteen buffers, and the allocator showed in
/// the cliques' time).
struct CliqueWorkspace::Buffers {
  std::vector<int> degree, start, by_degree, greedy, clique, queue, order;
  std::vector<char> in_core;
  Bits P;
  std::vector<std::uint64_t> xt;
  Graph sorted{0};
  std::deque<Level> levels;
};

CliqueWorkspace::CliqueWorkspace() : buffers_(std::make_unique<Buffers>()) {}
CliqueWorkspace::~CliqueWorkspace() = default;
CliqueWorkspace::CliqueWorkspace(CliqueWorkspace&&) noexcept = default;
CliqueWorkspace& CliqueWorkspace::operator=(CliqueWorkspace&&) noexcept = default;

CliqueResult maximumClique(const Graph& g, std::uint64_t work_limit) {
  CliqueWorkspace workspace;
  return maximumClique(g, work_limit, workspace);
}

CliqueResult maximumClique(const Graph& g, std::uint64_t work_limit, CliqueWorkspace& workspace) {
  if (g.size() == 0) return {};
  const int n = g.size();
  CliqueWorkspace::Buffers& w = *workspace.buffers_;
  std::vector<int>& degree = w.degree;
  degree.resize(static_cast<std::size_t>(n));
  for (int v = 0; v < n; ++v) degree[v] = g.degree(v);
  // The vertices by degree, highest first, equal degrees by index: a counting sort, degrees
  // lying in [0, n] (n with a self-loop; std::stable_sort was 1.3% of ipd0-32's samples).
  std::vector<int>& start = w.start;  // counts, then where each degree begins
  start.assign(static_cast<std::size_t>(n) + 1, 0);
  for (int v = 0; v < n; ++v) ++start[degree[v]];
  for (int d = n, at = 0; d >= 0; --d) {
    const int count = start[d];
    start[d] = at;
    at += count;
  }
  std::vector<int>& by_degree = w.by_degree;
  by_degree.resize(static_cast<std::size_t>(n));
  for (int v = 0; v < n; ++v) by_degree[start[degree[v]]++] = v;
  greedyClique(g, by_degree, w.greedy, w.clique, w.P);
  const std::vector<int>& greedy = w.greedy;
  // Only vertices of at least |greedy| neighbours among themselves can lie in a larger clique;
  // they keep the degree order, highest first: tighter colour bounds early (MCQ's initial order).
  coreOf(g, degree, static_cast<int>(greedy.size()), w.in_core, w.queue);
  std::vector<int>& order = w.order;
  order.clear();
  for (const int v : by_degree)
    if (w.in_core[v]) order.push_back(v);
  CliqueResult r;
  r.vertices = greedy;
  if (order.size() > greedy.size()) {
    relabelled(g, order, w.sorted, w.xt);
    CliqueResult found = Search(w.sorted, work_limit, greedy.size(), w.levels).run();
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

GraphWorkspace::GraphWorkspace() : impl_(std::make_unique<Impl>()) {}
GraphWorkspace::~GraphWorkspace() = default;
GraphWorkspace::GraphWorkspace(GraphWorkspace&&) noexcept = default;
GraphWorkspace& GraphWorkspace::operator=(GraphWorkspace&&) noexcept = default;

Graph consistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& model, float e_gmax,
                       GraphWorkspace* workspace, const NormalAgreement& normals) {
  std::optional<GraphWorkspace> own;  // made only for a caller without one
  GraphWorkspace& ws = workspace != nullptr ? *workspace : own.emplace();
  const int n = static_cast<int>(cps.size());
  Graph g(n);
  // Pairs of one scene point come in runs (a point's candidates): the scene distance, and with
  // it the band of accepted model distances, is computed once per run and shared by its pairs.
  // Row i is computed from its diagonal word on (the 64 x 64 blocks on and above the diagonal);
  // the blocks below are those above, bit-transposed. Both tests are the same either way round,
  // so this is the graph of every (i, j) computed in full.
  std::vector<int> run_start;  // first pair of each run of equal scene points, then n
  for (int i = 0; i < n; ++i)
    if (i == 0 || cps[i].scene != cps[i - 1].scene) run_start.push_back(i);
  run_start.push_back(n);
  const bool angles = normals.tolerance > 0 && normals.scene_normals != nullptr && normals.model_normals != nullptr;
  std::array<std::vector<float>, 6> storage;
  const Columns columns = columnsOf(cps, model, angles ? normals.model_normals : nullptr, storage);
  const float tolerance = normals.tolerance * std::numbers::pi_v<float> / 180.0f;
  const int runs = static_cast<int>(run_start.size()) - 1;
  tbb::parallel_for(tbb::blocked_range<int>(0, runs, 4), [&](const tbb::blocked_range<int>& range) {  // runs apart
    Bands& bands = ws.impl().local<Bands>();  // the thread's (every value read is written first)
    for (auto* v : {&bands.low2, &bands.high2, &bands.cos_low, &bands.cos_high})
      if (v->size() < cps.size()) v->resize(cps.size());
    for (int r = range.begin(); r < range.end(); ++r) {
      const int first_row = run_start[r];
      const std::uint32_t si = cps[first_row].scene;
      // The bands of the columns from the row's diagonal word on, run by run.
      const auto first_run = std::upper_bound(run_start.begin(), run_start.end(), first_row / 64 * 64) - run_start.begin() - 1;
      for (auto q = first_run; q < runs; ++q) {
        const std::uint32_t sq = cps[run_start[q]].scene;
        const Band band = bandOf((scene[sq] - scene[si]).norm(), e_gmax);
        const auto from = static_cast<std::size_t>(run_start[q]), to = static_cast<std::size_t>(run_start[q + 1]);
        std::fill(bands.low2.begin() + from, bands.low2.begin() + to, band.low2);
        std::fill(bands.high2.begin() + from, bands.high2.begin() + to, band.high2);
        if (!angles) continue;
        const CosineBand cosines = cosineBandOf((*normals.scene_normals)[si].dot((*normals.scene_normals)[sq]), tolerance);
        std::fill(bands.cos_low.begin() + from, bands.cos_low.begin() + to, cosines.low);
        std::fill(bands.cos_high.begin() + from, bands.cos_high.begin() + to, cosines.high);
      }
      for (int i = first_row; i < run_start[r + 1]; ++i) {
        std::uint64_t* row = g.mutableRow(i);
        linkRow(columns, bands, i, n, i / 64, row);
        row[i / 64] &= ~(1ull << (i % 64));
      }
    }
  });
  g.mirrorUpper();
  return g;
}

}  // namespace binpose
