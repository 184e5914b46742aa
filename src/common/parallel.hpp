// When the engine's loops fork threads.
#pragma once
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <omp.h>

namespace ces {

// Loops over fewer items (particles, contacts, bodies) than this run on one
// thread: below it OpenMP's fork and join cost more than the threads save.
inline constexpr std::ptrdiff_t kParallelMin = 256;

// How many chunks of `size` items cover n items, the last one short.
constexpr std::size_t chunk_count(std::size_t n, std::size_t size) { return (n + size - 1) / size; }

// A T on cache lines of its own, for the per-chunk buffers that threads
// fill side by side (neighbouring chunks may run on different threads). A
// std::vector's header is 24 bytes: packed, the neighbours' headers share
// lines, and every push_back moves a line between the cores, so that two
// threads can run the broadphase's sweep slower than one.
template <class T>
struct alignas(64) OwnLine : T {};

// fn(c) for every chunk c in [0, count), each once, on the threads. Each
// thread runs its own contiguous share in order, as a static schedule
// would, then takes what is left of the others' shares from their ends.
// On a machine whose cores run at unequal speeds at times (a VM with a busy
// neighbour), static halves wait for the slow one. A dynamic schedule
// evens that out but hands chunks to whichever core is free, so their data
// moves between the cores every pass, which costs on a quiet machine.
// Here a chunk changes core only when its owner is behind. What
// fn computes must depend on c alone (fixed chunks), never on the thread.
template <class Fn>
void for_each_chunk(std::size_t count, bool parallel, Fn&& fn) {
  const int threads = parallel && count > 1 ? omp_get_max_threads() : 1;
  if (threads == 1) {
    for (std::size_t c = 0; c < count; ++c) fn(c);
    return;
  }
  // A share's remaining chunks [front, back), packed in one word so that
  // its owner (at the front) and a thief (at the back) never take the same.
  struct alignas(64) Share {
    std::atomic<std::uint64_t> span;
  };
  static thread_local std::unique_ptr<Share[]> buffer;
  static thread_local int capacity = 0;
  if (capacity < threads) {
    buffer = std::make_unique<Share[]>(std::size_t(threads));
    capacity = threads;
  }
  // Named through a pointer: inside the region the thread_local would be
  // each worker's own.
  Share* shares = buffer.get();
  const auto n = std::uint64_t(count);
  for (int t = 0; t < threads; ++t)
    shares[t].span.store(n * std::uint64_t(t) / std::uint64_t(threads) |
                             (n * std::uint64_t(t + 1) / std::uint64_t(threads)) << 32,
                         std::memory_order_relaxed);
  auto take = [](Share& share, bool front, std::size_t& c) {
    std::uint64_t span = share.span.load(std::memory_order_relaxed);
    for (;;) {
      const std::uint64_t lo = span & 0xffffffffu, hi = span >> 32;
      if (lo >= hi) return false;
      const std::uint64_t next = front ? (lo + 1) | hi << 32 : lo | (hi - 1) << 32;
      if (share.span.compare_exchange_weak(span, next, std::memory_order_relaxed)) {
        c = std::size_t(front ? lo : hi - 1);
        return true;
      }
    }
  };
#pragma omp parallel num_threads(threads)
  {
    const int t = omp_get_thread_num();
    std::size_t c = 0;
    while (take(shares[t], true, c)) fn(c);
    // The others' leftovers; a share whose thread the team lacks too.
    for (int k = 1; k < threads; ++k)
      while (take(shares[(t + k) % threads], false, c)) fn(c);
  }
}

// fn(c, begin, end) for the fixed chunks [c chunk, (c + 1) chunk) of
// [0, n), the last one short, by for_each_chunk.
template <class Fn>
void for_each_range(std::size_t n, std::size_t chunk, bool parallel, Fn&& fn) {
  for_each_chunk(chunk_count(n, chunk), parallel,
                 [&](std::size_t c) { fn(c, c * chunk, std::min(n, (c + 1) * chunk)); });
}

// Items (contacts, bodies, particles) per chunk of a reduction or of
// for_each_index; fixed, so sums do not depend on threads. Small, so that
// two threads share even a few thousand contacts evenly (in chunks of
// 2,048, 5,000 contacts split 4,096 to 904).
inline constexpr std::size_t kReduceChunk = 256;

// fn(i) for every i in [0, n), in fixed chunks of kReduceChunk items by
// for_each_range, on the threads above kParallelMin items. Particles and
// contacts are ordered in space, so the costly ones (on the drum, asleep,
// in a pile) come in runs: static halves would leave one thread waiting
// where for_each_chunk hands it the rest of the other's share.
template <class Fn>
void for_each_index(std::size_t n, Fn&& fn) {
  for_each_range(n, kReduceChunk, std::ptrdiff_t(n) > kParallelMin,
                 [&](std::size_t, std::size_t begin, std::size_t end) {
                   for (std::size_t i = begin; i < end; ++i) fn(i);
                 });
}

// fn(begin, end, part) over fixed chunks of n items in parallel (by
// for_each_range), the parts added in chunk order: the same bits for any
// thread count. Part needs += and a default constructor that gives the
// neutral element.
template <class Part, class ChunkFn>
Part reduce_chunks(std::size_t n, ChunkFn fn) {
  // Grows only: one buffer per instantiation and thread of the caller.
  // (Named through a reference: inside the parallel loop the thread_local
  // itself would be each worker's own, empty, instance.)
  static thread_local std::vector<Part> buffer;
  std::vector<Part>& partial = buffer;
  partial.assign(chunk_count(n, kReduceChunk), Part{});
  for_each_range(
      n, kReduceChunk, std::ptrdiff_t(n) > kParallelMin,
      [&](std::size_t c, std::size_t begin, std::size_t end) { fn(begin, end, partial[c]); });
  Part total{};
  for (const Part& part : partial) total += part;
  return total;
}

// fn(begin, end) over [0, n) in fixed chunks of `chunk` items, by
// for_each_chunk, each chunk's bounds moved forward past any run they
// would cut (items i - 1 and i with same(i - 1, i) are of one run): every
// run is in one chunk, so a run's items may write to one place without a
// race, and the chunks do not depend on the threads.
template <class Same, class Fn>
void for_each_run_chunk(std::size_t n, std::size_t chunk, Same same, Fn fn) {
  const std::size_t chunks = chunk_count(n, chunk);
  auto bound = [&](std::size_t c) {
    std::size_t i = std::min(n, c * chunk);
    while (i > 0 && i < n && same(i - 1, i)) ++i;
    return i;
  };
  for_each_chunk(chunks, true, [&](std::size_t c) { fn(bound(c), bound(c + 1)); });
}

// v[i] becomes v[0] + ... + v[i - 1] (v[0] becomes 0), in parallel over
// fixed blocks: integers, so the sums are exact whatever the threads.
template <class T>
void exclusive_scan(std::vector<T>& v) {
  constexpr std::size_t kBlock = 4096;
  const std::size_t n = v.size(), blocks = chunk_count(n, kBlock);
  // Grows only, per thread of the caller: a step allocates nothing.
  static thread_local std::vector<T> buffer;
  std::vector<T>& first = buffer;
  first.assign(blocks + 1, T{});
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (std::size_t b = 0; b < blocks; ++b) {
    T sum{};
    for (std::size_t i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i) sum += v[i];
    first[b + 1] = sum;
  }
  for (std::size_t b = 0; b < blocks; ++b) first[b + 1] += first[b];
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (std::size_t b = 0; b < blocks; ++b) {
    T sum = first[b];
    for (std::size_t i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i) {
      const T x = v[i];
      v[i] = sum;
      sum += x;
    }
  }
}

// out = the i in [0, n) with keep(i), in increasing order, found in
// parallel over fixed chunks.
template <class Keep>
void select_in_order(std::size_t n, Keep keep, std::vector<std::uint32_t>& out) {
  constexpr std::size_t kBlock = 4096;
  const std::size_t blocks = chunk_count(n, kBlock);
  static thread_local std::vector<std::uint32_t> buffer;  // grows only
  std::vector<std::uint32_t>& first = buffer;
  first.assign(blocks + 1, 0);
  auto block = [&](std::size_t b, auto&& fn) {
    for (std::size_t i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i)
      if (keep(i)) fn(std::uint32_t(i));
  };
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (std::size_t b = 0; b < blocks; ++b) block(b, [&](std::uint32_t) { ++first[b]; });
  exclusive_scan(first);
  out.resize(first[blocks]);
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (std::size_t b = 0; b < blocks; ++b) {
    std::uint32_t at = first[b];
    block(b, [&](std::uint32_t i) { out[at++] = i; });
  }
}

}  // namespace ces
