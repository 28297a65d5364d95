// Accumulator voting and fourth-spread selection (thesis 4.3-4.4).
#include <binpose/voting.hpp>

#include <binpose/geometry.hpp>
#include <binpose/symmetry.hpp>

#include "simd.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <numeric>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

namespace binpose {
namespace {

/// Value at sorted position `pos` of the histogram's data.
std::uint32_t valueAt(std::span<const std::uint32_t> histogram, std::uint64_t pos) {
  std::uint64_t seen = 0;
  for (std::size_t v = 0; v < histogram.size(); ++v) {
    seen += histogram[v];
    if (seen > pos) return static_cast<std::uint32_t>(v);
  }
  return static_cast<std::uint32_t>(histogram.size() - 1);
}

/// Median of sorted positions [begin, begin + count).
double medianOf(std::span<const std::uint32_t> histogram, std::uint64_t begin, std::uint64_t count) {
  const std::uint64_t mid = begin + count / 2;
  if (count % 2 == 1) return valueAt(histogram, mid);
  return 0.5 * (double(valueAt(histogram, mid - 1)) + double(valueAt(histogram, mid)));
}

}  // namespace

Fourths fourthsOfHistogram(std::span<const std::uint32_t> histogram) {
  std::uint64_t n = 0;
  for (const auto c : histogram) n += c;
  if (n == 0) throw Error("fourth spread of an empty data set");
  const std::uint64_t half = (n + 1) / 2;  // the median goes in both halves when n is odd
  return {medianOf(histogram, 0, half), medianOf(histogram, n - half, half)};
}

namespace {

/// Eq. 10-11 on the histogram of a data set (histogram[v]: how many hold v): the value above
/// which one is an upper outlier, x_u + 3 xi_s.
double outlierLimit(std::span<const std::uint32_t> histogram) {
  const Fourths f = fourthsOfHistogram(histogram);
  return f.upper + 3.0 * f.spread();  // eq. 11
}

}  // namespace

void upperOutliers(std::span<const std::uint32_t> values, std::vector<std::uint32_t>& histogram,
                   std::vector<std::size_t>& out) {
  out.clear();
  if (values.empty()) return;
  const std::uint32_t top = *std::max_element(values.begin(), values.end());
  histogram.assign(std::size_t{top} + 1, 0);
  for (const auto v : values) ++histogram[v];
  const double limit = outlierLimit(histogram);
  if (!(top > limit)) return;  // eq. 11: no upper outlier, no candidate
  for (std::size_t i = 0; i < values.size(); ++i)
    if (values[i] > limit) out.push_back(i);
}

namespace {

/// Orders indices by more votes first (value(i)), then by index.
template <typename Value>
auto moreVotes(Value value) {
  return [value](std::size_t a, std::size_t b) { return value(a) != value(b) ? value(a) > value(b) : a < b; };
}

/// Eq. 12 on the upper outliers `picked` (ascending indices, value(i) their votes): with keep <= 1
/// the maximum (ties all kept), else the `keep` with most votes, ties by index, best first.
template <typename Value>
void keepBest(std::vector<std::size_t>& picked, int keep, Value value) {
  if (picked.empty()) return;
  if (keep <= 1) {
    std::uint32_t top = 0;
    for (const auto i : picked) top = std::max<std::uint32_t>(top, value(i));
    std::erase_if(picked, [&](std::size_t i) { return value(i) != top; });
    return;
  }
  const auto cut = picked.begin() + std::min<std::ptrdiff_t>(keep, static_cast<std::ptrdiff_t>(picked.size()));
  std::partial_sort(picked.begin(), cut, picked.end(), moreVotes(value));
  picked.erase(cut, picked.end());
}

}  // namespace

std::vector<std::size_t> selectCandidates(std::span<const std::uint32_t> values, int keep) {
  std::vector<std::uint32_t> histogram;
  std::vector<std::size_t> picked;
  upperOutliers(values, histogram, picked);
  keepBest(picked, keep, [values](std::size_t i) { return values[i]; });
  return picked;
}

namespace {

/// Adds `times` to the counter of each model point in `ids` (16-bit counters, or bytes when the
/// point's votes add up to at most 255).
template <class Count>
void countList(Count* votes, std::span<const ModelDatabase::PointId> ids, std::uint16_t times) {
  // Four ids per load: the increments bound this loop, and a load per id took about 5% more
  // (BM_LocalVotes 108-111 ms against 104-105). No branch: every id counts.
  auto add = [&](std::uint64_t id) { votes[id] = static_cast<Count>(votes[id] + times); };
  std::size_t i = 0;
  for (; i + 4 <= ids.size(); i += 4) {
    std::uint64_t four;
    std::memcpy(&four, ids.data() + i, sizeof four);  // the four in either byte order: each counted once
    add(four & 0xFFFF);
    add((four >> 16) & 0xFFFF);
    add((four >> 32) & 0xFFFF);
    add(four >> 48);
  }
  for (; i < ids.size(); ++i) add(ids[i]);
}

/// Starts fetching the cache lines of a list's first 128 ids (a whole list of fewer points than
/// ModelDatabase::denseListSize()). Fetched 4 lists before they were counted, the lists were
/// still missed there: each is counted in some 10-20 ns, a memory access takes longer.
void prefetchIds(std::span<const ModelDatabase::PointId> ids) {
  if (ids.empty()) return;
  const auto first = reinterpret_cast<std::uintptr_t>(ids.data()) & ~std::uintptr_t{63};
  const auto end = reinterpret_cast<std::uintptr_t>(ids.data() + std::min<std::size_t>(ids.size(), 128));
  for (std::uintptr_t at = first; at < end; at += 64) __builtin_prefetch(reinterpret_cast<const void*>(at));
}

/// The lines of a bitset fetched before it is added; the rest as it is added, that many lines
/// ahead. All of its 8 lines asked for at the lookup, a point's ~41 bitsets fill the miss
/// buffers and the prefetches stall (docs/benchmarks.md, where the time goes).
constexpr std::size_t kBitsetLinesAhead = 2;

#if defined(__x86_64__)
BINPOSE_AVX2_INLINE __m256i load256(const std::uint64_t* at) { return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(at)); }

/// Carry-save adder, bit by bit: a + b + c = sum + 2 carry.
BINPOSE_AVX2_INLINE void carrySave(__m256i& sum, __m256i& carry, __m256i a, __m256i b, __m256i c) {
  const __m256i u = _mm256_xor_si256(a, b);
  sum = _mm256_xor_si256(u, c);
  carry = _mm256_or_si256(_mm256_and_si256(a, b), _mm256_and_si256(u, c));
}

/// Adds x (one bit per counter) at bit `from` of 256 vertical counters held as NP bit planes
/// (plane[p]: bit p of each counter), carrying up.
template <int NP>
BINPOSE_AVX2_INLINE void addAt(__m256i (&plane)[NP], __m256i x, int from) {
#pragma GCC unroll 8
  for (int p = from; p < NP; ++p) {
    const __m256i carry = _mm256_and_si256(plane[p], x);
    plane[p] = _mm256_xor_si256(plane[p], x);
    x = carry;
  }
}

/// votes[i] += the count of 256 vertical counters (np planes), 32 counters at a step: each
/// plane's 32 bits spread over bytes, each byte testing its bit, weighted 2^p. Byte counters
/// take the 32 sums as they are; 16-bit ones widened.
template <class Count>
__attribute__((target("avx2"))) void addPlanes(const __m256i* plane, int np, Count* votes) {
  alignas(32) std::uint32_t chunk[8][8];
  for (int p = 0; p < np; ++p) _mm256_store_si256(reinterpret_cast<__m256i*>(chunk[p]), plane[p]);
  const __m256i spread = _mm256_setr_epi8(0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 2, 2, 2, 2, 2, 2, 2, 2, 3, 3, 3,
                                          3, 3, 3, 3, 3);
  const __m256i bit = _mm256_set1_epi64x(static_cast<long long>(0x8040201008040201ull));
  for (int c = 0; c < 8; ++c) {
    __m256i sum = _mm256_setzero_si256();
    for (int p = 0; p < np; ++p) {
      const __m256i lanes = _mm256_shuffle_epi8(_mm256_set1_epi32(static_cast<int>(chunk[p][c])), spread);
      const __m256i on = _mm256_cmpeq_epi8(_mm256_and_si256(lanes, bit), bit);
      sum = _mm256_add_epi8(sum, _mm256_and_si256(on, _mm256_set1_epi8(static_cast<char>(1 << p))));
    }
    auto* at = reinterpret_cast<__m256i*>(votes + 32 * c);
    if constexpr (sizeof(Count) == 1) {
      _mm256_storeu_si256(at, _mm256_add_epi8(_mm256_loadu_si256(at), sum));
    } else {
      _mm256_storeu_si256(at, _mm256_add_epi16(_mm256_loadu_si256(at), _mm256_cvtepu8_epi16(_mm256_castsi256_si128(sum))));
      _mm256_storeu_si256(
          at + 1, _mm256_add_epi16(_mm256_loadu_si256(at + 1), _mm256_cvtepu8_epi16(_mm256_extracti128_si256(sum, 1))));
    }
  }
}

/// votes[m] += the number of the `count` (< 2^NP) bitsets holding m, 256 model points at a
/// step: their counts kept as NP bit planes in registers (vertical counters), each bitset's
/// 256 bits added in a few logic operations, four at a time through carry-save adders
/// (Harley-Seal), the planes turned into counts once per step.
template <int NP, class Count>
__attribute__((target("avx2"))) void addBitsetsSliced(Count* votes, const std::uint64_t* const* bits,
                                                      std::size_t count, std::size_t blocks) {
  for (std::size_t b = 0; b < blocks; ++b) {
    __m256i plane[NP];
    for (int p = 0; p < NP; ++p) plane[p] = _mm256_setzero_si256();
    const std::size_t at = 4 * b;
    std::size_t l = 0;
    if constexpr (NP >= 3) {
      for (; l + 4 <= count; l += 4) {
        __m256i twos_a, twos_b, fours;
        carrySave(plane[0], twos_a, plane[0], load256(bits[l] + at), load256(bits[l + 1] + at));
        carrySave(plane[0], twos_b, plane[0], load256(bits[l + 2] + at), load256(bits[l + 3] + at));
        carrySave(plane[1], fours, plane[1], twos_a, twos_b);
        addAt<NP>(plane, fours, 2);
      }
    }
    for (; l < count; ++l) addAt<NP>(plane, load256(bits[l] + at), 0);
    // Each bitset's next lines asked for as its last ones are added (two 256-bit steps a line),
    // kBitsetLinesAhead lines ahead: its first ones were asked for when its key was looked up.
    if ((b & 1) == 0 && b + 2 * kBitsetLinesAhead < blocks)
      for (std::size_t k = 0; k < count; ++k) __builtin_prefetch(bits[k] + at + 8 * kBitsetLinesAhead);
    addPlanes(plane, NP, votes + 256 * b);
  }
}

/// The same for any count, 255 bitsets (8 planes) at a time (byte counters: at most 255 in all).
template <class Count>
void addBitsets(Count* votes, std::span<const std::uint64_t* const> bits, std::size_t blocks) {
  for (std::size_t start = 0; start < bits.size(); start += 255) {
    const std::size_t count = std::min<std::size_t>(255, bits.size() - start);
    const std::uint64_t* const* from = bits.data() + start;
    switch (std::bit_width(count)) {
      case 1: addBitsetsSliced<1, Count>(votes, from, count, blocks); break;
      case 2: addBitsetsSliced<2, Count>(votes, from, count, blocks); break;
      case 3: addBitsetsSliced<3, Count>(votes, from, count, blocks); break;
      case 4: addBitsetsSliced<4, Count>(votes, from, count, blocks); break;
      case 5: addBitsetsSliced<5, Count>(votes, from, count, blocks); break;
      case 6: addBitsetsSliced<6, Count>(votes, from, count, blocks); break;
      case 7: addBitsetsSliced<7, Count>(votes, from, count, blocks); break;
      default: addBitsetsSliced<8, Count>(votes, from, count, blocks); break;
    }
  }
}
#else
template <class Count>
void addBitsets(Count*, std::span<const std::uint64_t* const>, std::size_t) {}
#endif

// The accumulator's scans, 8 counters to an SSE4.1 step where the build has it (x86-64-v2 and
// up; GCC's -O2 leaves these loops scalar): 2.2 and 2.1 us a 4000-point accumulator scalar.

/// The largest count.
std::uint16_t largestVote(std::span<const std::uint16_t> votes) {
  std::size_t i = 0;
  std::uint16_t top = 0;
#if defined(__SSE4_1__)
  __m128i most = _mm_setzero_si128();
  for (; i + 8 <= votes.size(); i += 8)
    most = _mm_max_epu16(most, _mm_loadu_si128(reinterpret_cast<const __m128i*>(votes.data() + i)));
  // The largest lane: the smallest of the complements (phminposuw).
  top = static_cast<std::uint16_t>(0xFFFF - _mm_extract_epi16(_mm_minpos_epu16(_mm_xor_si128(most, _mm_set1_epi16(-1))), 0));
#endif
  for (; i < votes.size(); ++i) top = std::max(top, votes[i]);
  return top;
}

/// The indices of the counts above `above` (< 65535), ascending, into `out` (cleared).
void votesAbove(std::span<const std::uint16_t> votes, std::uint16_t above, std::vector<std::size_t>& out) {
  out.clear();
  std::size_t i = 0;
#if defined(__SSE4_1__)
  // 32 counters tested at once (v > above <=> max(v, above + 1) == v).
  const __m128i least = _mm_set1_epi16(static_cast<short>(above + 1));
  auto over = [&](std::size_t at) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(votes.data() + at));
    return _mm_cmpeq_epi16(_mm_max_epu16(v, least), v);
  };
  for (; i + 32 <= votes.size(); i += 32) {
    // The lanes' all-ones or zeros packed to bytes, a bit per counter: the set bits are taken
    // in order without a branch per counter.
    const auto low = static_cast<std::uint32_t>(_mm_movemask_epi8(_mm_packs_epi16(over(i), over(i + 8))));
    const auto high = static_cast<std::uint32_t>(_mm_movemask_epi8(_mm_packs_epi16(over(i + 16), over(i + 24))));
    for (std::uint32_t bits = low | (high << 16); bits != 0; bits &= bits - 1)
      out.push_back(i + static_cast<std::size_t>(std::countr_zero(bits)));
  }
#endif
  for (; i < votes.size(); ++i)
    if (votes[i] > above) out.push_back(i);
}

#if defined(__x86_64__)
/// The accumulator (a multiple of 32 counters) packed to bytes in order, each saturated at 255,
/// into `bytes`; returns the largest count.
__attribute__((target("avx2"))) std::uint16_t packVotes(std::span<const std::uint16_t> votes, std::uint8_t* bytes) {
  __m256i most = _mm256_setzero_si256();
  for (std::size_t i = 0; i < votes.size(); i += 32) {
    const __m256i a = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(votes.data() + i));
    const __m256i b = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(votes.data() + i + 16));
    most = _mm256_max_epu16(most, _mm256_max_epu16(a, b));
    // packus interleaves the two inputs' 128-bit halves; the permute puts them back in order.
    const __m256i packed = _mm256_permute4x64_epi64(_mm256_packus_epi16(a, b), 0xD8);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(bytes + i), packed);
  }
  const __m128i half = _mm_max_epu16(_mm256_castsi256_si128(most), _mm256_extracti128_si256(most, 1));
  // The largest lane: the smallest of the complements (phminposuw).
  return static_cast<std::uint16_t>(0xFFFF - _mm_extract_epi16(_mm_minpos_epu16(_mm_xor_si128(half, _mm_set1_epi16(-1))), 0));
}

/// The largest of the byte counters (a multiple of 32 of them).
__attribute__((target("avx2"))) std::uint8_t largestByte(std::span<const std::uint8_t> votes) {
  __m256i most = _mm256_setzero_si256();
  for (std::size_t i = 0; i < votes.size(); i += 32)
    most = _mm256_max_epu8(most, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(votes.data() + i)));
  __m128i half = _mm_max_epu8(_mm256_castsi256_si128(most), _mm256_extracti128_si256(most, 1));
  half = _mm_max_epu8(half, _mm_srli_si128(half, 8));
  half = _mm_max_epu8(half, _mm_srli_si128(half, 4));
  half = _mm_max_epu8(half, _mm_srli_si128(half, 2));
  half = _mm_max_epu8(half, _mm_srli_si128(half, 1));
  return static_cast<std::uint8_t>(_mm_cvtsi128_si32(half) & 0xFF);
}

/// The indices of the byte counters (a multiple of 32 of them) above `above` (< 255),
/// ascending, into `out` (cleared): 32 tested at once, their bits taken in order.
__attribute__((target("avx2"))) void bytesAbove(std::span<const std::uint8_t> votes, std::uint8_t above,
                                                std::vector<std::size_t>& out) {
  out.clear();
  const __m256i least = _mm256_set1_epi8(static_cast<char>(above + 1));  // v > above <=> max(v, above + 1) == v
  for (std::size_t i = 0; i < votes.size(); i += 32) {
    const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(votes.data() + i));
    auto bits = static_cast<std::uint32_t>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(_mm256_max_epu8(v, least), v)));
    for (; bits != 0; bits &= bits - 1) out.push_back(i + static_cast<std::size_t>(std::countr_zero(bits)));
  }
}

/// 32 bytes as bits: bit j for a byte equal to base + j (j < 8), none for any other. The byte
/// less base, wrapped, is under 8 only for those eight values; min(., 8) puts any other at 8,
/// which bit_of maps to none.
BINPOSE_AVX2_INLINE __m256i valueBits(const std::uint8_t* at, __m256i bit_of, __m256i base, __m256i eight) {
  const __m256i x = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(at));
  return _mm256_shuffle_epi8(bit_of, _mm256_min_epu8(_mm256_sub_epi8(x, base), eight));
}

/// equal[j] = how many of the bytes (a multiple of 128) equal from + j, for j < 8: each byte
/// turned into one bit (bit j for from + j, none for any other value), and the bits at each
/// position counted down the bytes as eight bit planes (vertical counters, carry-save adders
/// four bytes' bits at a time, as addBitsetsSliced). 1.7x as fast as comparing each value.
__attribute__((target("avx2"))) void countEqual(std::span<const std::uint8_t> bytes, int from, std::uint64_t (&equal)[8]) {
  const __m256i bit_of = _mm256_setr_epi8(1, 2, 4, 8, 16, 32, 64, -128, 0, 0, 0, 0, 0, 0, 0, 0, 1, 2, 4, 8, 16, 32, 64, -128,
                                          0, 0, 0, 0, 0, 0, 0, 0);
  const __m256i base = _mm256_set1_epi8(static_cast<char>(from));
  const __m256i eight = _mm256_set1_epi8(8);
  for (auto& e : equal) e = 0;
  for (std::size_t start = 0; start < bytes.size();) {
    // Eight planes count to 255: at most 252 steps of 32 bytes (63 of 128) between read-outs.
    const std::size_t end = std::min(bytes.size(), start + 63 * 128);
    __m256i plane[8];
    for (auto& p : plane) p = _mm256_setzero_si256();
    for (std::size_t i = start; i < end; i += 128) {
      const std::uint8_t* at = bytes.data() + i;
      __m256i twos_a, twos_b, fours;
      carrySave(plane[0], twos_a, plane[0], valueBits(at, bit_of, base, eight), valueBits(at + 32, bit_of, base, eight));
      carrySave(plane[0], twos_b, plane[0], valueBits(at + 64, bit_of, base, eight), valueBits(at + 96, bit_of, base, eight));
      carrySave(plane[1], fours, plane[1], twos_a, twos_b);
      addAt<8>(plane, fours, 2);
    }
    alignas(32) std::uint64_t word[8][4];
    for (int p = 0; p < 8; ++p) _mm256_store_si256(reinterpret_cast<__m256i*>(word[p]), plane[p]);
    for (int b = 0; b < 8; ++b) {
      const std::uint64_t mask = 0x0101010101010101ull << b;  // bit b of every byte
      for (int p = 0; p < 8; ++p)
        equal[b] += static_cast<std::uint64_t>(std::popcount(word[p][0] & mask) + std::popcount(word[p][1] & mask) +
                                               std::popcount(word[p][2] & mask) + std::popcount(word[p][3] & mask))
                    << p;
    }
    start = end;
  }
}
#endif

/// histogram[v]: the votes equal to v, from 1 up to where the fourths of the non-zero votes lie
/// (the votes above put together in the next bin, where no fourth reaches), counted from
/// `bytes` (the votes as bytes, a multiple of 128 of them); false when top > 255.
bool lowHistogram(std::span<const std::uint8_t> bytes, std::uint16_t top, std::vector<std::uint32_t>& histogram) {
#if defined(__x86_64__)
  if (top > 255) return false;
  std::uint64_t equal[8];  // equal[j]: the votes equal to from + j
  countEqual(bytes, 0, equal);
  const std::uint64_t n = bytes.size() - equal[0];  // the non-zero votes
  const std::uint64_t half = (n + 1) / 2;
  const std::uint64_t last = n - half + half / 2;  // the upper fourth's last position (fourthsOfHistogram)
  histogram.assign(1, 0);
  std::uint64_t binned = 0;  // the non-zero votes binned so far
  for (int from = 0;; from += 8) {
    if (from > 0) countEqual(bytes, from, equal);
    for (int j = from == 0 ? 1 : 0; j < 8; ++j) {
      histogram.push_back(static_cast<std::uint32_t>(equal[j]));
      binned += equal[j];
      if (binned > last || from + j == top) {  // positions 0 to last binned
        if (binned < n) histogram.push_back(static_cast<std::uint32_t>(n - binned));
        return true;
      }
    }
  }
#else
  (void)bytes, (void)top, (void)histogram;
  return false;
#endif
}

/// histogram[v]: the votes equal to v, for v from 1 to top (histogram[0] = 0).
void fullHistogram(std::span<const std::uint16_t> votes, std::uint16_t top, std::vector<std::uint32_t>& histogram) {
  // Eight histograms side by side, so that runs of equal votes do not wait on each other (four:
  // BM_LocalVotes 65.3-69.0 ms; eight: 64.1-65.4).
  const std::size_t bins = std::size_t{top} + 1;
  histogram.assign(8 * bins, 0);
  // Through plain pointers, one per histogram: indexing the vector by lane took 1.7x as long.
  std::uint32_t* h[8];
  for (std::size_t l = 0; l < 8; ++l) h[l] = histogram.data() + l * bins;
  const std::uint16_t* const v = votes.data();
  const std::size_t n = votes.size();
  std::size_t id = 0;
  for (; id + 8 <= n; id += 8) {
    ++h[0][v[id]];
    ++h[1][v[id + 1]];
    ++h[2][v[id + 2]];
    ++h[3][v[id + 3]];
    ++h[4][v[id + 4]];
    ++h[5][v[id + 5]];
    ++h[6][v[id + 6]];
    ++h[7][v[id + 7]];
  }
  for (; id < n; ++id) ++h[0][v[id]];
  for (std::size_t b = 0; b < bins; ++b)
    h[0][b] += h[1][b] + h[2][b] + h[3][b] + h[4][b] + h[5][b] + h[6][b] + h[7][b];
  histogram.resize(bins);
  histogram[0] = 0;
}

}  // namespace

VoteCut upperOutlierCut(std::span<const std::uint16_t> votes, std::vector<std::uint8_t>& bytes,
                        std::vector<std::uint32_t>& histogram) {
  // Eq. 10-11 need only the fourths of the non-zero votes, which lie in the histogram's lower
  // part. With AVX2, the votes as bytes (when the top is under 256) are counted from the bottom,
  // eight values a pass, until the histogram holds the upper fourth's last position: on IPD
  // obj 8's 4000 points 2.1 passes on average (1 to 6), each a few logic operations on 32
  // bytes at a time, instead of a scalar increment per model point.
  VoteCut cut;
  bool counted = false;
#if defined(__x86_64__)
  if (votes.size() % 128 == 0 && detail::haveAvx2()) {
    bytes.resize(votes.size());
    cut.top = packVotes(votes, bytes.data());
    counted = cut.top > 0 && lowHistogram(bytes, cut.top, histogram);
  } else {
    cut.top = largestVote(votes);
  }
#else
  cut.top = largestVote(votes);
#endif
  if (cut.top == 0) return cut;
  if (!counted) fullHistogram(votes, cut.top, histogram);
  cut.limit = outlierLimit(histogram);
  return cut;
}

template <class Count>
void Voter::countDense(std::vector<Count>& counters) {
  // Bitsets rather than id lists for the lists of a 48th of the model points and more: with n_M
  // = 4000, a list costs about 64 logic operations on 256-bit words and the points' counts
  // about 1.5 operations a point, against about 1 ns a point listed (IPD obj 8's points each
  // had 41 such lists, 31000 points in all, from a 32nd). A 48th measured faster than a 32nd
  // or a 16th on the bench bins, and no slower than a 64th.
  if (!dense_lists_.empty()) addBitsets(counters.data(), dense_lists_, counters.size() / 256);
  dense_lists_.clear();
}

Voter::Voter(const ModelDatabase& db, int keep, float spacing, const Orbits* orbits)
    : db_(db), keep_(keep), spacing_(spacing),
      orbits_(orbits != nullptr && !orbits->cyclic ? orbits : nullptr),
      classes_(orbits != nullptr && orbits->cyclic ? orbits : nullptr) {
  if (orbits != nullptr && orbits->of.size() != db.model().points.size())
    throw Error(fmt::format("orbits of {} points for a model of {}", orbits->of.size(), db.model().points.size()));
  counters_ = orbits_ != nullptr ? orbits_->count : db.model().points.size();
  votes_.assign(256 * ((counters_ + 255) / 256), 0);
  bitsets_ = orbits_ == nullptr && detail::haveAvx2();
  if (detail::haveAvx2()) narrow_.assign(votes_.size(), 0);
}

void Voter::useBitsets(bool on) { bitsets_ = on && orbits_ == nullptr && detail::haveAvx2(); }

void Voter::groupKeys() {
  // Open addressing on a table of at least twice as many slots as keys, each slot the key's
  // place in distinct_ (kEmpty: none); used slots are emptied again at the end. The votes are
  // sums, so the keys' order does not matter, only that equal keys are counted together
  // (std::sort did this before, 2-3% of the detection's time).
  constexpr std::uint32_t kEmpty = ~std::uint32_t{0};
  distinct_.clear();
  const std::size_t size = std::bit_ceil(std::max<std::size_t>(64, 2 * keys_.size()));
  if (slots_.size() < size) slots_.assign(size, kEmpty);
  const std::size_t mask = slots_.size() - 1;
  const int shift = 32 - std::countr_zero(slots_.size());
  for (const std::uint32_t key : keys_) {
    std::size_t h = (key * 0x9E3779B1u) >> shift;  // Fibonacci hashing: the product's top bits
    while (slots_[h] != kEmpty && distinct_[slots_[h]].key != key) h = (h + 1) & mask;
    if (slots_[h] == kEmpty) {
      slots_[h] = static_cast<std::uint32_t>(distinct_.size());
      distinct_.push_back({key, 1, static_cast<std::uint32_t>(h)});
    } else {
      ++distinct_[slots_[h]].count;
    }
  }
  for (const Distinct& d : distinct_) slots_[d.slot] = kEmpty;
}

void Voter::votePoint(const Points& points, const Points& normals, std::uint32_t k,
                      std::span<const std::uint32_t> partners, std::vector<Correspondence>& out) {
  const KeySpace& keys = db_.keySpace();
  // L_k (eq. 9): the model points under the key of every feature (ss_k -> ss_o). Features of the
  // same key (pairs on one plane, say) are counted together: the same sums, fewer increments.
  keys_.clear();
  featureKeys(points[k], normals[k], points, normals, partners, k, keys, keys_);
  groupKeys();
  lists_.clear();
  std::uint64_t added = 0;  // the votes the lists add, all told: no count is larger
  // The keys' table entries are fetched kKeysAhead keys before they are read.
  constexpr std::size_t kKeysAhead = 16;
  for (std::size_t a = 0; a < std::min(kKeysAhead, distinct_.size()); ++a) db_.prefetch(distinct_[a].key);
  for (std::size_t a = 0; a < distinct_.size(); ++a) {
    if (a + kKeysAhead < distinct_.size()) db_.prefetch(distinct_[a + kKeysAhead].key);
    const std::uint32_t key = distinct_[a].key;
    const auto ids = db_.lookup(key);
    if (ids.empty()) continue;
    const auto times = static_cast<std::uint16_t>(distinct_[a].count);
    added += times;
    // The lists lie far apart in the table (which does not fit in the cache): each one's lines
    // are fetched as soon as it is known, some 60 keys before the lists are counted.
    if (orbits_ != nullptr) {
      lists_.push_back({orbits_->lookup(key), times});  // the orbits of those points
      prefetchIds(lists_.back().ids);
      continue;
    }
    // A long list as its bitset, once per vote it adds (rarely more than once).
    const auto bits = bitsets_ && times <= kMostBitsetRepeats ? db_.denseBits(key) : std::span<const std::uint64_t>{};
    if (bits.empty()) {
      lists_.push_back({ids, times});
      prefetchIds(ids);
      continue;
    }
    for (std::size_t at = 0; at < std::min(bits.size(), 8 * kBitsetLinesAhead); at += 8) __builtin_prefetch(bits.data() + at);
    dense_lists_.insert(dense_lists_.end(), times, bits.data());
  }
  // When the lists add up to at most 255 votes (a point with fewer partners than that, each
  // feature adding one), no count passes 255: the counts go into bytes, half the accumulator
  // to add the bitsets into, scan and clear, and no packing for the histogram.
  const bool narrow = !narrow_.empty() && added <= 255;
  const auto tally = [&](auto& counters) {
    for (const List& list : lists_) countList(counters.data(), list.ids, list.times);
    countDense(counters);
    select(k, narrow, out);
    std::fill_n(counters.begin(), counters_, 0);  // the padding stays zero
  };
  if (narrow) tally(narrow_);
  else tally(votes_);
}

void Voter::select(std::uint32_t k, bool narrow, std::vector<Correspondence>& out) {
  // A_k is the model points with a vote (eq. 9-10): its histogram is the accumulator's without
  // the zeros (the padding's zeros included in the scans).
#if defined(__x86_64__)
  if (narrow) {
    VoteCut cut;
    cut.top = largestByte(narrow_);
    if (cut.top == 0) return;
    lowHistogram(narrow_, cut.top, histogram_);  // the top is under 256: always counted
    cut.limit = outlierLimit(histogram_);
    if (!(cut.top > cut.limit)) return;  // eq. 11: no upper outlier, no candidate
    bytesAbove(narrow_, static_cast<std::uint8_t>(cut.limit), outliers_);  // v > limit <=> v > floor(limit)
    keepCandidates(k, cut, [this](std::size_t m) { return std::uint32_t{narrow_[m]}; }, out);
    return;
  }
#endif
  (void)narrow;
  const VoteCut cut = upperOutlierCut(votes_, bytes_, histogram_);
  if (!(cut.top > cut.limit)) return;  // eq. 11: no upper outlier, no candidate (nor any vote)
  // Votes are whole: v > limit <=> v > floor(limit).
  votesAbove(std::span<const std::uint16_t>(votes_.data(), counters_), static_cast<std::uint16_t>(cut.limit), outliers_);
  keepCandidates(k, cut, [this](std::size_t m) { return std::uint32_t{votes_[m]}; }, out);
}

template <class Value>
void Voter::keepCandidates(std::uint32_t k, VoteCut cut, Value value, std::vector<Correspondence>& out) {
  const std::uint16_t top = cut.top;
  const auto above = static_cast<std::uint16_t>(cut.limit);
  // A body of revolution's accumulator is over its orbits: each one's first point stands for it.
  // A part of cyclic symmetry's over its points: each stands for its class, by the class member.
  const auto model_point = [this](std::size_t m) {
    return static_cast<std::uint32_t>(orbits_ != nullptr ? orbits_->member[m] : classes_ != nullptr ? classes_->member[classes_->of[m]] : m);
  };
  if (keep_ <= 1 || spacing_ <= 0) {
    keepBest(outliers_, keep_, value);
    for (const std::size_t m : outliers_) out.push_back({k, model_point(m)});
    return;
  }
  // The upper outliers best first (counted into order, or sorted a batch at a time: usually the
  // first batch holds all that are kept); each kept unless a better one kept lies within spacing_.
  // Distances between model points (class members: a class's images are one candidate), or
  // between orbits in the axis's half-plane.
  const auto where = [this](std::uint32_t m) -> Vec3 {
    return orbits_ != nullptr ? orbits_->inPlane(orbits_->of[m]) : db_.model().points[m];
  };
  const std::size_t first = out.size();
  const auto better = moreVotes(value);
  const std::size_t batch = 4 * static_cast<std::size_t>(keep_);
  // Votes are whole and lie in (above, top]: when that range is short, sortByCell's counting
  // sort over top - votes (most first; outliers_ holds ascending indices, and the sort keeps
  // their order) gives moreVotes's order at once, where partial_sort's comparisons took a fifth
  // of select().
  const std::size_t range = std::size_t{top} - above;
  std::size_t sorted = 0;
  if (range <= 2 * outliers_.size() + 64) {
    rank_.resize(outliers_.size());
    for (std::size_t r = 0; r < outliers_.size(); ++r) rank_[r] = top - value(outliers_[r]);
    sortByCell(rank_, range, bucket_, order_);
    by_votes_.resize(outliers_.size());
    for (std::size_t r = 0; r < order_.size(); ++r) by_votes_[r] = outliers_[order_[r]];
    outliers_.swap(by_votes_);
    sorted = outliers_.size();
  }
  for (std::size_t r = 0; r < outliers_.size(); ++r) {
    if (r == sorted) {
      sorted = std::min(outliers_.size(), sorted + batch);
      std::partial_sort(outliers_.begin() + static_cast<std::ptrdiff_t>(r),
                        outliers_.begin() + static_cast<std::ptrdiff_t>(sorted), outliers_.end(), better);
    }
    const Vec3 m = where(model_point(outliers_[r]));
    bool near = false;
    for (std::size_t c = first; c < out.size() && !near; ++c) near = (where(out[c].model) - m).squaredNorm() < spacing_ * spacing_;
    if (near) continue;
    out.push_back({k, model_point(outliers_[r])});
    if (out.size() - first >= static_cast<std::size_t>(keep_)) break;
  }
}

void Voter::vote(const Points& points, const Points& normals, std::span<const std::uint32_t> group,
                 std::vector<Correspondence>& out) {
  if (group.size() >= 65535) throw Error(fmt::format("sub-group of {} points is too large to vote", group.size()));
  for (const std::uint32_t k : group) votePoint(points, normals, k, group, out);
}

ParallelVoter::ParallelVoter(const ModelDatabase& db, int keep, float spacing, const Orbits* orbits)
    : voters_([&db, keep, spacing, orbits] { return Voter(db, keep, spacing, orbits); }) {}

void ParallelVoter::vote(const Points& points, const Points& normals, std::span<const std::uint32_t> group,
                         std::vector<Correspondence>& out) {
  if (group.size() >= 65535) throw Error(fmt::format("sub-group of {} points is too large to vote", group.size()));
  constexpr std::size_t kChunk = 16;  // points per task; each task's pairs kept apart, joined in order
  const std::size_t chunks = (group.size() + kChunk - 1) / kChunk;
  if (parts_.size() < chunks) parts_.resize(chunks);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    Voter& voter = voters_.local();
    parts_[c].clear();
    for (std::size_t i = c * kChunk; i < std::min(group.size(), (c + 1) * kChunk); ++i)
      voter.votePoint(points, normals, group[i], group, parts_[c]);
  });
  for (std::size_t c = 0; c < chunks; ++c) out.insert(out.end(), parts_[c].begin(), parts_[c].end());
}

struct NeighbourhoodVoter::Local {
  Voter voter;
  std::vector<std::uint32_t> found;
  std::vector<std::uint32_t> partners;
  std::vector<Correspondence> out;
};

NeighbourhoodVoter::NeighbourhoodVoter(const ModelDatabase& db, const Points& points, const Points& normals, float radius,
                                       int keep, std::span<const std::uint32_t> partners, float spacing,
                                       const Orbits* orbits)
    : points_(points), normals_(normals), radius_(radius), voted_(points.size(), 0), candidates_(points.size()) {
  if (partners.empty()) {
    partners_.resize(points.size());
    std::iota(partners_.begin(), partners_.end(), 0u);
  } else {
    partners_.assign(partners.begin(), partners.end());
  }
  for (const auto o : partners_) partner_points_.push_back(points[o]);
  grid_ = std::make_unique<PointGrid>(partner_points_, 0.5f * radius);
  // Each thread's copy of this one (its own accumulator and buffers).
  locals_ = std::make_unique<tbb::enumerable_thread_specific<Local>>(Local{Voter(db, keep, spacing, orbits), {}, {}, {}});
}

NeighbourhoodVoter::~NeighbourhoodVoter() = default;

void NeighbourhoodVoter::vote(std::span<const std::uint32_t> voters) {
  pending_.clear();
  for (const auto k : voters)
    if (!voted_[k]) {
      voted_[k] = 1;
      pending_.push_back(k);
    }
  // Four points a task at least: a batch of sub-groups has about 70 new voters of some 15 us
  // each, and tasks of 16 left the other core idle at the end. On ipd8-16 (two threads, 36
  // batches) the votes' wall time less their busy time per thread: 0.76-0.90 ms, against
  // 1.15-1.41 ms with 16.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pending_.size(), 4), [&](const tbb::blocked_range<std::size_t>& range) {
    Local& l = locals_->local();
    for (std::size_t v = range.begin(); v < range.end(); ++v) {
      const std::uint32_t k = pending_[v];
      grid_->within(points_[k], radius_, l.found);
      if (l.found.size() >= 65535)
        throw Error(fmt::format("{} points within {} mm of a point: too many to vote", l.found.size(), radius_));
      l.partners.clear();
      for (const auto o : l.found) l.partners.push_back(partners_[o]);
      l.out.clear();
      l.voter.votePoint(points_, normals_, k, l.partners, l.out);
      candidates_[k].reserve(l.out.size());  // one allocation
      for (const Correspondence& c : l.out) candidates_[k].push_back(c.model);
    }
  });
}

std::vector<std::vector<std::uint32_t>> voteNeighbourhoods(const ModelDatabase& db, const Points& points,
                                                           const Points& normals, float radius, int keep,
                                                           std::span<const std::uint32_t> voters,
                                                           std::span<const std::uint32_t> partners) {
  NeighbourhoodVoter voter(db, points, normals, radius, keep, partners);
  std::vector<std::uint32_t> all;
  if (voters.empty()) {
    all.resize(points.size());
    std::iota(all.begin(), all.end(), 0u);
    voters = all;
  }
  voter.vote(voters);
  return voter.release();
}

}  // namespace binpose
