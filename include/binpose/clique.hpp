#pragma once
// Maximum clique of the correspondence graph (thesis 4.5): exact branch and bound on bitsets
// with greedy-colouring bounds (Tomita & Seki 2003; San Segundo et al. 2011), with a work bound.
#include <binpose/voting.hpp>

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace binpose {

/// An undirected graph on vertices 0..n-1 as rows of 64-bit words.
class Graph {
 public:
  explicit Graph(int n) : n_(n), words_((n + 63) / 64), bits_(static_cast<std::size_t>(n) * words_, 0) {}
  /// The graph of n vertices and no edge (its memory kept).
  void reset(int n) {
    n_ = n;
    words_ = (n + 63) / 64;
    bits_.assign(static_cast<std::size_t>(n) * words_, 0);
  }
  void addEdge(int a, int b) {
    if (a == b) return;
    bits_[static_cast<std::size_t>(a) * words_ + b / 64] |= 1ull << (b % 64);
    bits_[static_cast<std::size_t>(b) * words_ + a / 64] |= 1ull << (a % 64);
  }
  [[nodiscard]] bool adjacent(int a, int b) const { return (row(a)[b / 64] >> (b % 64)) & 1ull; }
  [[nodiscard]] const std::uint64_t* row(int v) const { return bits_.data() + static_cast<std::size_t>(v) * words_; }
  /// Row v to write whole words at once; the caller keeps the graph symmetric and v not its own neighbour.
  [[nodiscard]] std::uint64_t* mutableRow(int v) { return bits_.data() + static_cast<std::size_t>(v) * words_; }
  [[nodiscard]] int size() const { return n_; }
  [[nodiscard]] int words() const { return words_; }
  [[nodiscard]] int degree(int v) const;
  /// Removes every edge of the listed vertices (they stay, alone).
  void isolate(std::span<const int> vertices);
  /// Makes the graph symmetric from its edges (i, j), j > i: each row's words below its
  /// diagonal word are set from the 64 x 64 blocks above (bit-transposed), and each diagonal
  /// block takes its transpose's bits too. For graph builders that fill each row from its
  /// diagonal word on.
  void mirrorUpper();

 private:
  int n_, words_;
  std::vector<std::uint64_t> bits_;
};

struct CliqueResult {
  std::vector<int> vertices;  ///< the largest clique found, ascending
  bool exact = true;          ///< false when the work bound stopped the search early
  std::uint64_t nodes = 0;    ///< branch-and-bound nodes expanded
};

/// Transposes a 64 x 64 bit block in place (bit c of a[r] <-> bit r of a[c]): on AVX2
/// registers where the CPU has them and `simd` is set, else by scalar swaps (Warren, Hacker's
/// Delight 7-3); the same bits either way. The graphs' mirror and the clique search's
/// relabelling work in such blocks.
void transposeBits64(std::array<std::uint64_t, 64>& a, bool simd = true);

/// The per-thread buffers of a consistency graph's rows, kept by a caller that builds many graphs
/// (a matcher slot) so that they are made once; not shared by two graphs built at the same time.
/// Without one, a graph builder makes its own for the call.
class GraphWorkspace {
 public:
  GraphWorkspace();
  ~GraphWorkspace();
  GraphWorkspace(GraphWorkspace&&) noexcept;
  GraphWorkspace& operator=(GraphWorkspace&&) noexcept;
  struct Impl;  ///< src/graph_workspace.hpp
  [[nodiscard]] Impl& impl() { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

/// The consistency graph's test of normals, beyond the thesis: CP_i and CP_j must also turn
/// their normals by the same angle in the scan as in the model, within `tolerance` degrees (the
/// angle is one of a point-pair feature's, Drost et al. 2010). A wrong pair of equal distances
/// on a noisy scan seldom has it too.
struct NormalAgreement {
  const Points* scene_normals = nullptr;
  const Points* model_normals = nullptr;
  float tolerance = 0;  ///< degrees; 0: no test
};

/// Geometric consistency graph (eq. 13-16): CP_i and CP_j are linked when the model and scene
/// distances between them differ by less than e_gmax (and, with `normals`, their normals agree).
Graph consistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& model, float e_gmax,
                       GraphWorkspace* workspace = nullptr, const NormalAgreement& normals = {});

/// A maximum clique of g. A greedy clique (grown from the highest-degree vertices) gives a
/// lower bound L; the search then runs only on the vertices of the L-core (those keeping at
/// least L neighbours among themselves), where every larger clique lies. It expands at most
/// `work_limit` nodes; if it has to stop, the best clique found so far is returned with
/// exact = false. Deterministic.
CliqueResult maximumClique(const Graph& g, std::uint64_t work_limit = 1000);

/// maximumClique's buffers, for a caller that searches many graphs: reused from one call to the
/// next (one workspace per thread of the caller's: a call writes into it).
class CliqueWorkspace {
 public:
  CliqueWorkspace();
  ~CliqueWorkspace();
  CliqueWorkspace(CliqueWorkspace&&) noexcept;
  CliqueWorkspace& operator=(CliqueWorkspace&&) noexcept;

 private:
  struct Buffers;
  std::unique_ptr<Buffers> buffers_;
  friend CliqueResult maximumClique(const Graph& g, std::uint64_t work_limit, CliqueWorkspace& workspace);
};

/// maximumClique with the buffers of `workspace`; the same result.
CliqueResult maximumClique(const Graph& g, std::uint64_t work_limit, CliqueWorkspace& workspace);

}  // namespace binpose
