#pragma once
// The SIMD kernels of the votes (thesis eq. 9-11): counting a key's list of model points into
// the accumulator, adding long lists as bitsets (AVX2, vertical counters), and scanning the
// accumulator for its largest count, its histogram and the counts above the outlier limit.
// Each kernel is a plain function with a scalar path where the instruction set lacks it; the
// algorithm they serve (Voter, voting.cpp) reads as eq. 8-12. Only voting.cpp includes this.
#include <binpose/model_database.hpp>

#include "simd.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

namespace binpose::kernels {

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
inline void prefetchIds(std::span<const ModelDatabase::PointId> ids) {
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
inline std::uint16_t largestVote(std::span<const std::uint16_t> votes) {
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
inline void votesAbove(std::span<const std::uint16_t> votes, std::uint16_t above, std::vector<std::size_t>& out) {
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
inline __attribute__((target("avx2"))) std::uint16_t packVotes(std::span<const std::uint16_t> votes, std::uint8_t* bytes) {
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
inline __attribute__((target("avx2"))) std::uint8_t largestByte(std::span<const std::uint8_t> votes) {
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
inline __attribute__((target("avx2"))) void bytesAbove(std::span<const std::uint8_t> votes, std::uint8_t above,
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
inline __attribute__((target("avx2"))) void countEqual(std::span<const std::uint8_t> bytes, int from, std::uint64_t (&equal)[8]) {
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
inline bool lowHistogram(std::span<const std::uint8_t> bytes, std::uint16_t top, std::vector<std::uint32_t>& histogram) {
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
inline void fullHistogram(std::span<const std::uint16_t> votes, std::uint16_t top, std::vector<std::uint32_t>& histogram) {
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

}  // namespace binpose::kernels
