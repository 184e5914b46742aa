// The APGD kernel (CcpProblem::apgd_step, apgd_gradient and the bodies'
// pass, scatter_bodies): four contacts to a vector (GCC/Clang vector
// extensions; one AVX instruction each where the instruction set has it,
// two SSE2 halves otherwise). kernel_baseline.cpp, kernel_avx2.cpp and
// kernel_avx512.cpp each include it once, with CES_KERNEL_ISA naming their
// instruction set; the code below runs beyond baseline x86-64 only in
// those (isa.hpp chooses among them). Lane l holds contact 4 b + l of
// block b. The AVX-512 build's gradient pass takes two blocks to a
// 512-bit vector (d8: lanes 0-3 block b, 4-7 block b + 1): the same
// operations on each lane, and every sum adds block b's terms before
// block b + 1's (add_in_order), so it gives the bits of two 4-lane blocks.
//
// It runs on world rows: a contact's three rows hold its impulse as a world
// vector P = n x_n + t1 x_t1 + t2 x_t2, and its gradient is the relative
// velocity at the contact plus the bias along the normal, J v + b n. The
// frame (n, t1, t2) is orthonormal, so this change of variables keeps every
// norm and dot product APGD takes and the iteration is the same, but the
// tangents are never needed: the cone is |P - n (n.P)| <= mu n.P, the
// impulses the bodies' pass sums are the iterate itself (no vector of world
// impulses written and read back), and the gather gives the gradient
// without three dot products. Only n and mu are stored: 16 bytes a contact
// instead of 44. solve_apgd changes to world rows at its start and back at
// its end (to_world, to_local).
//
// The rows keep their layout, three doubles per contact: a block's 12 are
// loaded as three vectors and transposed to x, y, z lanes.
#include "dynamics/ccp.hpp"

#include <algorithm>
#include <cstring>
#include <type_traits>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "common/parallel.hpp"

namespace ces {

// After the includes, so that the headers' inline functions (shared by
// the three builds) stay baseline x86-64. AVX-512VL gives the same 256-bit
// vectors and the same arithmetic to the bit, but 32 registers where AVX2
// has 16, so a block's lanes stay out of the stack. Not FMA: a fused
// multiply-add rounds once where the baseline build rounds twice.
#if !defined(CES_KERNEL_ISA)
#error "kernel.inl is included by kernel_*.cpp, which define CES_KERNEL_ISA"
#endif
#pragma GCC push_options
#if CES_KERNEL_ISA == 2
#pragma GCC target("avx512f,avx512vl,avx2,prefer-vector-width=256")
#define CES_KERNEL_NAMESPACE kernel_avx512
#elif CES_KERNEL_ISA == 1
#pragma GCC target("avx2")
#define CES_KERNEL_NAMESPACE kernel_avx2
#else
#define CES_KERNEL_NAMESPACE kernel_baseline
#endif
// The helpers' own namespace for each build (kernel_baseline, kernel_avx2,
// kernel_avx512): the three builds' helpers differ, and the instantiations
// below, which have external linkage, use their types.
namespace CES_KERNEL_NAMESPACE {

using d4 = double __attribute__((vector_size(32)));
using f4 = float __attribute__((vector_size(16)));
constexpr std::size_t kVec = 4;  // lanes of d4: CcpProblem::kLanes
#if CES_KERNEL_ISA == 2
using d8 = double __attribute__((vector_size(64)));
#endif
template <class V>
using MaskOf = decltype(V{} < V{});
template <class V>
constexpr std::size_t kLanesOf = sizeof(V) / sizeof(double);

[[gnu::always_inline]] inline d4 load(const double* p) {
  d4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
[[gnu::always_inline]] inline void store(double* p, d4 v) { std::memcpy(p, &v, sizeof v); }
[[gnu::always_inline]] inline d4 widen(const float* p) {
#if defined(__AVX__)
  // One vcvtps2pd from memory: GCC 12 splits __builtin_convertvector into
  // two halves through the stack (5 instructions, 24 of them per block).
  return d4(_mm256_cvtps_pd(_mm_loadu_ps(p)));
#else
  f4 f;
  std::memcpy(&f, p, sizeof f);
  return __builtin_convertvector(f, d4);
#endif
}
[[gnu::always_inline]] inline d4 widen(const double* p) { return load(p); }
template <class V>
[[gnu::always_inline]] inline V select(MaskOf<V> mask, V a, V b) { return mask ? a : b; }
template <class V>
[[gnu::always_inline]] inline V vmax(V a, V b) { return select<V>(a < b, b, a); }  // std::max(a, b)'s lanes
[[gnu::always_inline]] inline d4 vsqrt(d4 a) {
#if defined(__AVX__)
  return d4(_mm256_sqrt_pd(__m256d(a)));
#elif defined(__SSE2__)
  const __m128d lo = _mm_sqrt_pd(_mm_set_pd(a[1], a[0])), hi = _mm_sqrt_pd(_mm_set_pd(a[3], a[2]));
  return d4{lo[0], lo[1], hi[0], hi[1]};
#else
  return d4{std::sqrt(a[0]), std::sqrt(a[1]), std::sqrt(a[2]), std::sqrt(a[3])};
#endif
}
double lane_sum(d4 a) { return (a[0] + a[1]) + (a[2] + a[3]); }

// shuf<i...>(a, b): __builtin_shufflevector(a, b, i...) of four lanes; on
// d8, the same in each half (block b's lanes with block b's, b + 1's with
// b + 1's), so the transposes below serve both widths.
template <int i0, int i1, int i2, int i3>
[[gnu::always_inline]] inline d4 shuf(d4 a, d4 b) {
  return __builtin_shufflevector(a, b, i0, i1, i2, i3);
}
[[gnu::always_inline]] inline void row_store(double* p, std::size_t j, d4 v) { store(p + 4 * j, v); }
// acc += x[0]; acc += x[1]; acc += x[2].
[[gnu::always_inline]] inline void add_in_order(d4& acc, const d4 (&x)[3]) {
  for (const d4& t : x) acc += t;
}
#if CES_KERNEL_ISA == 2
template <int i0, int i1, int i2, int i3>
[[gnu::always_inline]] inline d8 shuf(d8 a, d8 b) {
  constexpr auto lo = [](int i) { return i < 4 ? i : i + 4; };
  constexpr auto hi = [](int i) { return i < 4 ? i + 4 : i + 8; };
  return __builtin_shufflevector(a, b, lo(i0), lo(i1), lo(i2), lo(i3), hi(i0), hi(i1), hi(i2),
                                 hi(i3));
}
[[gnu::always_inline]] inline d8 concat(d4 lo, d4 hi) {
  return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
}
[[gnu::always_inline]] inline d4 low(d8 v) { return __builtin_shufflevector(v, v, 0, 1, 2, 3); }
[[gnu::always_inline]] inline d4 high(d8 v) { return __builtin_shufflevector(v, v, 4, 5, 6, 7); }
[[gnu::always_inline]] inline void row_store(double* p, std::size_t j, d8 v) {
  store(p + 4 * j, low(v));
  store(p + 12 + 4 * j, high(v));
}
// Block b's three terms, then block b + 1's: the 4-lane order.
[[gnu::always_inline]] inline void add_in_order(d4& acc, const d8 (&x)[3]) {
  for (const d8& t : x) acc += low(t);
  for (const d8& t : x) acc += high(t);
}
[[gnu::always_inline]] inline d8 vsqrt(d8 a) {
  // Masked with every lane on: _mm512_sqrt_pd's undefined source trips GCC 12's
  // -Wmaybe-uninitialized.
  return d8(_mm512_mask_sqrt_pd(__m512d(a), 0xff, __m512d(a)));
}
[[gnu::always_inline]] inline bool all_lanes(MaskOf<d8> m) {
  return _mm512_test_epi64_mask(__m512i(m), __m512i(m)) == 0xff;
}
#endif

// A vector's rows j: a block's rows 4 j .. 4 j + 3 (it has 12); on d8, then
// the next block's, which follow them. row_store writes them back.
template <class V>
[[gnu::always_inline]] inline V row_load(const double* p, std::size_t j) {
  if constexpr (kLanesOf<V> == 4) return load(p + 4 * j);
#if CES_KERNEL_ISA == 2
  else return concat(load(p + 4 * j), load(p + 12 + 4 * j));
#endif
}
// The lanes of a block's four numbers at p (frame_'s, metric_'s); on d8,
// then the next block's, `stride` on.
template <class V, class T>
[[gnu::always_inline]] inline V block_lanes(const T* p, [[maybe_unused]] std::size_t stride) {
  if constexpr (kLanesOf<V> == 4) return widen(p);
#if CES_KERNEL_ISA == 2
  else return concat(widen(p), widen(p + stride));
#endif
}

// The x, y, z rows of a vector's contacts, lane = contact.
template <class V>
struct Lanes3 {
  V c[3];
};
// 12 doubles [x0 y0 z0 x1 y1 z1 ...], as three vectors a, <-> the lanes.
template <class V>
[[gnu::always_inline]] inline Lanes3<V> lanes_of(const V a[3]) {
  const V x01 = shuf<0, 3, 6, 7>(a[0], a[1]);
  const V y01 = shuf<1, 4, 7, 7>(a[0], a[1]);
  const V z01 = shuf<2, 5, 5, 5>(a[0], a[1]);
  return {{shuf<0, 1, 2, 5>(x01, a[2]), shuf<0, 1, 2, 6>(y01, a[2]), shuf<0, 1, 4, 7>(z01, a[2])}};
}
template <class V>
[[gnu::always_inline]] inline void rows_of(const Lanes3<V>& r, V a[3]) {
  const V &x = r.c[0], &y = r.c[1], &z = r.c[2];
  a[0] = shuf<0, 1, 4, 2>(shuf<0, 4, 1, 1>(x, y), z);
  a[1] = shuf<0, 1, 6, 2>(shuf<1, 5, 2, 2>(y, z), x);
  a[2] = shuf<0, 1, 7, 2>(shuf<2, 7, 3, 3>(z, x), y);
}

[[gnu::always_inline]] inline bool all_lanes(MaskOf<d4> m) {
#if defined(__AVX__)
  return _mm256_movemask_pd(__m256d(m)) == 0xf;
#else
  return (m[0] & m[1] & m[2] & m[3]) != 0;
#endif
}

// A vector's normals and friction coefficients, lane = contact.
template <class V>
struct FrameLanes {
  V n[3], mu;
};
// `stride`: frame_'s block (CcpProblem::kFrameBlock).
template <class V>
[[gnu::always_inline]] inline FrameLanes<V> load_frame(const StoredScalar* f, std::size_t stride) {
  return {{block_lanes<V>(f, stride), block_lanes<V>(f + kVec, stride),
           block_lanes<V>(f + 2 * kVec, stride)},
          block_lanes<V>(f + 3 * kVec, stride)};
}

// project_cone's cases on world rows, lane by lane: P = Π(z) onto
// |P - n (n.P)| <= mu n.P. A sticking contact keeps z as it is. The sliding
// case's square root and division are slow (tens of cycles, not pipelined),
// so a block none of whose lanes slides, most of a flow's blocks, skips
// them.
template <class V>
[[gnu::always_inline]] inline void project_cone(const FrameLanes<V>& F, Lanes3<V>& z) {
  const V* n = F.n;
  const V zn = n[0] * z.c[0] + n[1] * z.c[1] + n[2] * z.c[2];
  const V t[3] = {z.c[0] - n[0] * zn, z.c[1] - n[1] * zn, z.c[2] - n[2] * zn};
  const V s2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2], mu = F.mu, mu2 = mu * mu;
  const auto inside = (zn >= 0.0) & (s2 <= mu2 * zn * zn);
  const auto polar = (zn <= 0.0) & (mu2 * s2 <= zn * zn);
  const V zero = {}, pressing = vmax(zn, zero);  // a frictionless lane's normal part
  const auto frictionless = mu <= 0.0;
  const auto keep = ~frictionless & inside, clear = ~frictionless & ~inside & polar;
  if (all_lanes(keep | clear | frictionless)) {
    for (auto& c : z.c) c = select<V>(keep, c, zero);
    for (int c = 0; c < 3; ++c) z.c[c] = select<V>(frictionless, n[c] * pressing, z.c[c]);
    return;
  }
  const V s = vsqrt(s2);
  const V along = mu * s + zn, q = 1.0 / ((mu2 + 1.0) * s);
  const V pn = select<V>(frictionless, pressing, along * s * q), scale = mu * along * q;
  for (int c = 0; c < 3; ++c) {
    const V slid = n[c] * pn + select<V>(frictionless, zero, t[c] * scale);
    z.c[c] = select<V>(keep, z.c[c], select<V>(clear, zero, slid));
  }
}

// One number per contact (lane = contact) spread over a block's 12 rows,
// three to a contact, as row_load finds them: [c0 c0 c0 c1] [c1 c1 c2 c2]
// [c2 c3 c3 c3].
template <class V>
[[gnu::always_inline]] inline void spread_lanes(V c, V out[3]) {
  out[0] = shuf<0, 0, 0, 1>(c, c);
  out[1] = shuf<1, 1, 2, 2>(c, c);
  out[2] = shuf<2, 3, 3, 3>(c, c);
}

// The rows 3 k0 .. 3 k0 + 11 of a block: pointers into the vectors for a
// whole block, into zero-padded copies for the short last one (whose lanes
// past the contacts then compute zeros).
class BlockRows {
 public:
  BlockRows(std::size_t i0, std::size_t rows) : i0_(i0), rows_(rows) {}
  bool full() const { return rows_ == 12; }
  const double* in(ConstSpan v, int slot) {
    if (full()) return v.data() + i0_;
    std::fill_n(std::copy_n(v.data() + i0_, rows_, pad_[slot]), 12 - rows_, 0.0);
    return pad_[slot];
  }
  double* out(Span v, int slot) { return full() ? v.data() + i0_ : pad_[slot]; }
  void flush(Span v, int slot) const {
    if (!full()) std::copy_n(pad_[slot], rows_, v.data() + i0_);
  }

 private:
  std::size_t i0_, rows_;
  double pad_[6][12];  // filled only for the short block
};

// block(k0, count) over the contacts [begin, end) in blocks of four: the
// whole blocks with count a constant, so the hot loop has no padding code,
// then the short one.
template <class Block>
[[gnu::always_inline]] inline void for_blocks(std::size_t begin, std::size_t end, Block&& block) {
  std::size_t k0 = begin;
  for (; k0 + kVec <= end; k0 += kVec) block(k0, std::integral_constant<std::size_t, kVec>{});
  if (k0 < end) block(k0, end - k0);
}
// for_blocks, but in the AVX-512 build pair(k0) first takes the whole
// blocks two at a time (contacts k0 .. k0 + 7).
template <class Pair, class Block>
[[gnu::always_inline]] inline void for_vectors(std::size_t begin, std::size_t end,
                                               [[maybe_unused]] Pair&& pair, Block&& block) {
#if CES_KERNEL_ISA == 2
  for (; begin + 2 * kVec <= end; begin += 2 * kVec) pair(begin);
#endif
  for_blocks(begin, end, block);
}

// Lane sums of a trial's dd, d.gy and uphill (CcpProblem::TrialSums).
struct TrialLanes {
  d4 dd = {}, d_gy = {}, uphill = {};
};

// One vector's contacts of a trial (apgd_step): x1 = Π(y - step gy) into
// p1, with y = ca x - cb x_old and gy = ca gx - cb g_old (pold, pgold
// unread when cb = 0); adds its sums to `sums`. `metric_block`: metric_'s
// block (CcpProblem::kMetricBlock).
template <class V>
[[gnu::always_inline]] inline void trial_block(const double* px, const double* pold,
                                               const double* pgx, const double* pgold,
                                               CcpProblem::Momentum mo, double step,
                                               const FrameLanes<V>& F, const float* metric,
                                               std::size_t metric_block, double* p1,
                                               TrialLanes& sums) {
  // The contacts' steps and the weights of |d|^2 (CcpProblem::metric_),
  // spread over the rows: a row vector holds a contact's rows and the next's.
  V st[3], wd[3];
  spread_lanes(step * block_lanes<V>(metric, metric_block), st);
  spread_lanes(block_lanes<V>(metric + kVec, metric_block), wd);
  // In registers throughout: the rows transposed to lanes and back.
  V y[3], gy[3], z[3];
  for (std::size_t j = 0; j < 3; ++j) {
    y[j] = row_load<V>(px, j);
    gy[j] = row_load<V>(pgx, j);
    if (mo.cb != 0.0) {
      y[j] = mo.ca * y[j] - mo.cb * row_load<V>(pold, j);
      gy[j] = mo.ca * gy[j] - mo.cb * row_load<V>(pgold, j);
    }
    z[j] = y[j] - st[j] * gy[j];
  }
  Lanes3<V> r = lanes_of(z);
  project_cone(F, r);
  V x1[3], dd[3], d_gy[3], uphill[3];
  rows_of(r, x1);
  for (std::size_t j = 0; j < 3; ++j) {
    row_store(p1, j, x1[j]);
    const V v1 = x1[j], d = v1 - y[j];
    dd[j] = wd[j] * d * d;
    d_gy[j] = d * gy[j];
    uphill[j] = gy[j] * (v1 - row_load<V>(px, j));
  }
  add_in_order(sums.dd, dd);
  add_in_order(sums.d_gy, d_gy);
  add_in_order(sums.uphill, uphill);
}

// A block's lever arms (lever_ from contact k0 on: 24 numbers), component
// by component, lane = contact.
template <class T>
[[gnu::always_inline]] inline void levers(const T* L, d4 ra[3], d4 rb[3]) {
  for (std::size_t c = 0; c < 3; ++c) {
    ra[c] = d4{double(L[c]), double(L[6 + c]), double(L[12 + c]), double(L[18 + c])};
    rb[c] = d4{double(L[3 + c]), double(L[9 + c]), double(L[15 + c]), double(L[21 + c])};
  }
}
#if defined(__AVX__)
// The same for float arms, by a 4x4 transpose.
[[gnu::always_inline]] inline void levers(const float* L, d4 ra[3], d4 rb[3]) {
  // Contact l's [ax ay az bx] at L + 6 l, transposed; then its [by bz].
  __m128 r0 = _mm_loadu_ps(L), r1 = _mm_loadu_ps(L + 6), r2 = _mm_loadu_ps(L + 12),
         r3 = _mm_loadu_ps(L + 18);
  _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
  auto pair = [&](std::size_t l) {
    double d;  // two floats, by and bz, as one 8-byte load
    std::memcpy(&d, L + 6 * l + 4, sizeof d);
    return _mm_castpd_ps(_mm_set_sd(d));
  };
  const __m128 s01 = _mm_movelh_ps(pair(0), pair(1)), s23 = _mm_movelh_ps(pair(2), pair(3));
  ra[0] = d4(_mm256_cvtps_pd(r0));
  ra[1] = d4(_mm256_cvtps_pd(r1));
  ra[2] = d4(_mm256_cvtps_pd(r2));
  rb[0] = d4(_mm256_cvtps_pd(r3));
  rb[1] = d4(_mm256_cvtps_pd(_mm_shuffle_ps(s01, s23, _MM_SHUFFLE(2, 0, 2, 0))));
  rb[2] = d4(_mm256_cvtps_pd(_mm_shuffle_ps(s01, s23, _MM_SHUFFLE(3, 1, 3, 1))));
}
#endif
#if CES_KERNEL_ISA == 2
// Two blocks' lever arms (from contact k0 on: 48 numbers).
template <class T>
[[gnu::always_inline]] inline void levers(const T* L, d8 ra[3], d8 rb[3]) {
  d4 ra0[3], rb0[3], ra1[3], rb1[3];
  levers(L, ra0, rb0);
  levers(L + 24, ra1, rb1);
  for (std::size_t c = 0; c < 3; ++c) {
    ra[c] = concat(ra0[c], ra1[c]);
    rb[c] = concat(rb0[c], rb1[c]);
  }
}
#endif

// Body i[l]'s velocity in v as one vector (its fourth number the next
// body's, unused; dv, dw have a spare); on d8, with body i[l + 4]'s.
template <class V>
[[gnu::always_inline]] inline V body_row(const std::vector<Vec3>& v, const std::size_t* i,
                                         std::size_t l) {
  if constexpr (kLanesOf<V> == 4) return load(v[i[l]].data());
#if CES_KERNEL_ISA == 2
  else return concat(load(v[i[l]].data()), load(v[i[l + 4]].data()));
#endif
}

// g = J dv + b n of a vector's contacts (world rows): count (<= its lanes)
// contacts from a, b (body indices), frame F, lever arms and bias; lane =
// contact, lanes past count zero.
template <class V>
[[gnu::always_inline]] inline Lanes3<V> gather_block(const FrameLanes<V>& F,
                                                     const StoredScalar* lever,
                                                     const std::int32_t* a, const std::int32_t* b,
                                                     std::size_t count,
                                                     const std::vector<Vec3>& dv,
                                                     const std::vector<Vec3>& dw,
                                                     const double* bias) {
  constexpr std::size_t lanes_of_v = kLanesOf<V>;
  std::size_t ia[lanes_of_v], ib[lanes_of_v];
  for (std::size_t l = 0; l < lanes_of_v; ++l) {
    ia[l] = std::size_t(a[std::min(l, count - 1)]);
    ib[l] = std::size_t(b[std::min(l, count - 1)]);
  }
  // Four bodies' velocities (in each block) as x, y, z lanes: each loaded
  // as one vector and transposed, 11 instructions where gathering lane by
  // lane takes 16.
  auto lanes = [&](const std::vector<Vec3>& v, const std::size_t* i, V out[3]) {
    const V r0 = body_row<V>(v, i, 0), r1 = body_row<V>(v, i, 1), r2 = body_row<V>(v, i, 2),
            r3 = body_row<V>(v, i, 3);
    const V xz01 = shuf<0, 4, 2, 6>(r0, r1), y01 = shuf<1, 5, 3, 7>(r0, r1);
    const V xz23 = shuf<0, 4, 2, 6>(r2, r3), y23 = shuf<1, 5, 3, 7>(r2, r3);
    out[0] = shuf<0, 1, 4, 5>(xz01, xz23);
    out[1] = shuf<0, 1, 4, 5>(y01, y23);
    out[2] = shuf<2, 3, 6, 7>(xz01, xz23);
  };
  // Relative velocity at the contact points, component by component.
  V va[3], wa[3], vb[3], wb[3];
  lanes(dv, ia, va);
  lanes(dw, ia, wa);
  lanes(dv, ib, vb);
  lanes(dw, ib, wb);
  V ra[3], rb[3];
  levers(lever, ra, rb);
  const V b_n = block_lanes<V>(bias, kVec);
  Lanes3<V> g;
  for (int c = 0; c < 3; ++c) {
    const int c1 = (c + 1) % 3, c2 = (c + 2) % 3;  // w x r, as Eigen's cross
    const V rel = (vb[c] + (wb[c1] * rb[c2] - wb[c2] * rb[c1])) -
                  (va[c] + (wa[c1] * ra[c2] - wa[c2] * ra[c1]));
    g.c[c] = rel + b_n * F.n[c];
  }
  // Padding lanes (a short block, never on d8): zero, whatever the velocities.
  if (lanes_of_v == 4 && count < lanes_of_v) {
    const V lane = {0.0, 1.0, 2.0, 3.0};
    const auto valid = lane < double(count);
    for (auto& c : g.c) c = select<V>(valid, c, V{});
  }
  return g;
}

// g += eps (n.P) n, a yielding contact's spring (CcpProblem::softness), lane
// by lane; eps is 0 on a rigid lane.
[[gnu::always_inline]] inline void add_spring(const FrameLanes<d4>& F, d4 eps,
                                              const Lanes3<d4>& P, Lanes3<d4>& g) {
  const d4 pn = F.n[0] * P.c[0] + F.n[1] * P.c[1] + F.n[2] * P.c[2];
  for (int c = 0; c < 3; ++c) g.c[c] += eps * pn * F.n[c];
}

// A bilateral row's trial, as trial_block does a contact's.
void trial_row(double x, double x_old, double gx, double g_old, CcpProblem::Momentum mo,
               double step, double weight, double lo, double hi, double& x1,
               CcpProblem::TrialSums& sums) {
  const double y = mo.cb != 0.0 ? mo.ca * x - mo.cb * x_old : x;
  const double gy = mo.cb != 0.0 ? mo.ca * gx - mo.cb * g_old : gx;
  x1 = std::clamp(y - step * weight * gy, lo, hi);
  sums.dd += (x1 - y) * (x1 - y) / weight;
  sums.dnd -= (x1 - y) * gy;
  sums.uphill += gy * (x1 - x);
}

}  // namespace CES_KERNEL_NAMESPACE

using namespace CES_KERNEL_NAMESPACE;

template <Isa I>
void CcpProblem::scatter_bodies_on(const double* P, ConstSpan x, bool add_free,
                                   std::vector<Vec3>& dv, std::vector<Vec3>& dw,
                                   const std::vector<std::uint32_t>* only) const {
  const SolverBodies& B = *bodies_;
  const auto nb = std::ptrdiff_t(B.inv_mass.size());
  // At least a velocity per body; the kernel's own (dv_, dw_) have a spare
  // past them (assemble), which stays.
  if (dv.size() < B.inv_mass.size()) dv.resize(B.inv_mass.size());
  if (dw.size() < B.inv_mass.size()) dw.resize(B.inv_mass.size());
  auto one_body = [&](std::size_t u) __attribute__((always_inline)) {
    // Lanes x, y, z of a vector; the fourth is never read (the loads of
    // P and lever_ take the next number into it; both have a spare).
    // ang_zxy holds r x p rotated by a lane, (z, x, y): r p_yzx - r_yzx p
    // is that, with the products and differences of Eigen's cross, so it
    // needs two shuffles per contact instead of four, and one at the end.
    // The side's sign goes on p (exact), so the sums have the bits of the
    // scalar code's += and -=.
    d4 lin = {}, ang_zxy = {};
    for (std::uint32_t e = adj_.offset[u]; e < adj_.offset[u + 1]; ++e) {
      const std::uint32_t entry = adj_.entry[e], side = entry & 1;
      const std::size_t k = entry >> 1;
      const d4 sign = side ? d4{1.0, 1.0, 1.0, 1.0} : d4{-1.0, -1.0, -1.0, -1.0};
      const d4 p = sign * load(P + 3 * k);
      const d4 r = widen(&lever_[6 * k + 3 * side]);  // its fourth lane is not ours
      const d4 r_yzx = __builtin_shufflevector(r, r, 1, 2, 0, 3);
      const d4 p_yzx = __builtin_shufflevector(p, p, 1, 2, 0, 3);
      lin += p;
      ang_zxy += r * p_yzx - r_yzx * p;
    }
    const d4 ang = __builtin_shufflevector(ang_zxy, ang_zxy, 1, 2, 0, 3);
    // The record's [00 01 02 11] and [12 22 m -]: the inverse inertia's
    // columns are [00 01 02], [01 11 12], [02 12 22].
    const StoredScalar* record = &inverse_mass_[kMassStride * u];
    const d4 lo = widen(record), hi = widen(record + 4);
    const d4 col1 = __builtin_shufflevector(lo, hi, 1, 3, 4, 4);
    const d4 col2 = __builtin_shufflevector(lo, hi, 2, 4, 5, 5);
    const d4 mass = __builtin_shufflevector(hi, hi, 2, 2, 2, 2);
    const d4 a0 = __builtin_shufflevector(ang, ang, 0, 0, 0, 0);
    const d4 a1 = __builtin_shufflevector(ang, ang, 1, 1, 1, 1);
    const d4 a2 = __builtin_shufflevector(ang, ang, 2, 2, 2, 2);
    const d4 lin_v = mass * lin, ang_v = lo * a0 + col1 * a1 + col2 * a2;
    dv[u] = Vec3(lin_v[0], lin_v[1], lin_v[2]);
    dw[u] = Vec3(ang_v[0], ang_v[1], ang_v[2]);
    if (add_free) {
      dv[u] += B.v_free[u];
      dw[u] += B.w_free[u];
    }
  };
  // Chunks of bodies, as the contact passes' (reduce_chunks): each body's
  // sum is its own, so the bits do not depend on who runs it, nor on
  // whether the others run (`only`: the listed bodies alone).
  const std::size_t bodies = only ? only->size() : std::size_t(nb);
  auto body = [&](std::size_t i) { return only ? std::size_t((*only)[i]) : i; };
  for_each_range(bodies, kReduceChunk, std::ptrdiff_t(bodies) > kParallelMin,
                 [&](std::size_t, std::size_t begin, std::size_t end) {
                   for (std::size_t i = begin; i < end; ++i) one_body(body(i));
                 });
  add_row_impulses(x, dv, dw, only);
}

template <Isa I>
CcpProblem::TrialSums CcpProblem::apgd_step_on(ConstSpan x, ConstSpan x_old, Span x1, ConstSpan gx,
                                               ConstSpan g_old, Momentum mo, double step) const {
  static_assert(kLanes == kVec);
  const std::size_t nc = a_.size();
  const bool old = mo.cb != 0.0;
  auto pass = [&](std::size_t begin, std::size_t end, TrialSums& part) {
    TrialLanes sums;
    auto trial = [&]<class V>(V, std::size_t k0, const double* px, const double* pold,
                              const double* pgx, const double* pgold, double* p1)
                     __attribute__((always_inline)) {
      trial_block(px, pold, pgx, pgold, mo, step,
                  load_frame<V>(&frame_[k0 / kLanes * kFrameBlock], kFrameBlock),
                  &metric_[k0 / kLanes * kMetricBlock], kMetricBlock, p1, sums);
    };
    auto pair = [&]([[maybe_unused]] std::size_t k0) __attribute__((always_inline)) {
#if CES_KERNEL_ISA == 2
      const std::size_t i = 3 * k0;
      trial(d8{}, k0, &x[i], old ? &x_old[i] : &x[i], &gx[i], old ? &g_old[i] : &gx[i], &x1[i]);
#endif
    };
    for_vectors(begin, end, pair, [&](std::size_t k0, auto count) __attribute__((always_inline)) {
      BlockRows blk(3 * k0, 3 * count);
      const double *px = blk.in(x, 0), *pgx = blk.in(gx, 1);
      const double *pold = old ? blk.in(x_old, 2) : px, *pgold = old ? blk.in(g_old, 3) : pgx;
      trial(d4{}, k0, px, pold, pgx, pgold, blk.out(x1, 4));
      blk.flush(x1, 4);
    });
    part = {lane_sum(sums.dd), -lane_sum(sums.d_gy), lane_sum(sums.uphill)};
  };
  TrialSums total = reduce_chunks<TrialSums>(nc, pass);
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    const std::size_t i = 3 * nc + j;
    trial_row(x[i], old ? x_old[i] : 0.0, gx[i], old ? g_old[i] : 0.0, mo, step, row_metric_[j],
              rows_[j].lo, rows_[j].hi, x1[i], total);
  }
  return total;
}

template <Isa I>
CcpProblem::TrialSums CcpProblem::apgd_gradient_on(ConstSpan x1, Span g1, ConstSpan x,
                                                   ConstSpan x_old, Momentum mo, TrialSums& t,
                                                   const NextTrial& next) const {
  scatter_bodies_on<I>(x1.data(), x1, true, dv_, dw_);
  const double inv_s = diag_max_, s_res = 1.0 / inv_s;  // the residual's step
  const bool old = mo.cb != 0.0, ahead = !next.x2.empty(), ahead_old = next.momentum.cb != 0.0;
  const std::size_t nc = a_.size();
  // This iteration's sums and the next trial's, each added in chunk order
  // as two separate reductions would add them.
  struct Parts {
    TrialSums here, ahead;
    Parts& operator+=(const Parts& o) {
      here += o.here;
      ahead += o.ahead;
      return *this;
    }
  };
  auto pass = [&](std::size_t begin, std::size_t end, Parts& part) {
    d4 d_g1 = {}, res2 = {};
    TrialLanes sums;
    // The contacts of one vector from k0 on (count of them), their rows of
    // x1, x, x_old at p1, px, pold; writes their rows of g1 at pg. The
    // caller then makes the next trial (trial_block) if `ahead`.
    auto contacts = [&]<class V>(std::size_t k0, std::size_t count, const double* p1,
                                 const double* px, const double* pold, double* pg,
                                 const FrameLanes<V>& F) __attribute__((always_inline)) {
      Lanes3<V> g = gather_block(F, &lever_[6 * k0], &a_[k0], &b_[k0], count, dv_, dw_, &bias_[k0]);
      V rows1[3];
      for (std::size_t j = 0; j < 3; ++j) rows1[j] = row_load<V>(p1, j);
      const Lanes3<V> r1 = lanes_of(rows1);
      if constexpr (kLanesOf<V> == 4)  // the wider vectors take rigid blocks only
        if (soft_block_[k0 / kLanes]) add_spring(F, load(&softness_[k0]), r1, g);
      V rows_g[3], d_g[3], res_sq[3];
      rows_of(g, rows_g);
      // d.g1 with d = x1 - y, y made again as apgd_step made it (the same
      // bits): cheaper than storing y there and reading it here.
      for (std::size_t j = 0; j < 3; ++j) {
        row_store(pg, j, rows_g[j]);
        const V y =
            old ? mo.ca * row_load<V>(px, j) - mo.cb * row_load<V>(pold, j) : row_load<V>(px, j);
        d_g[j] = (rows1[j] - y) * rows_g[j];
      }
      add_in_order(d_g1, d_g);
      Lanes3<V> q;
      for (int c = 0; c < 3; ++c) q.c[c] = r1.c[c] - s_res * g.c[c];
      project_cone(F, q);
      for (int c = 0; c < 3; ++c) {
        const V res = (r1.c[c] - q.c[c]) * inv_s;
        res_sq[c] = res * res;
      }
      add_in_order(res2, res_sq);
    };
    auto block = [&](std::size_t k0, auto count) __attribute__((always_inline)) {
      BlockRows blk(3 * k0, 3 * count);
      const FrameLanes<d4> F = load_frame<d4>(&frame_[k0 / kLanes * kFrameBlock], kFrameBlock);
      const double *p1 = blk.in(x1, 0), *px = blk.in(x, 1), *pold = old ? blk.in(x_old, 2) : px;
      double* pg = blk.out(g1, 3);
      contacts(k0, count, p1, px, pold, pg, F);
      blk.flush(g1, 3);
      if (ahead) {  // x1 is the next trial's x, x its x_old, g1 its gx
        const double* pgold = ahead_old ? blk.in(next.gx, 4) : pg;
        trial_block(p1, px, pg, pgold, next.momentum, next.step, F,
                    &metric_[k0 / kLanes * kMetricBlock], kMetricBlock, blk.out(next.x2, 5), sums);
        blk.flush(next.x2, 5);
      }
    };
    // Two rigid blocks at a time, straight from the vectors; the springs'
    // blocks one by one.
    auto pair = [&]([[maybe_unused]] std::size_t k0) __attribute__((always_inline)) {
#if CES_KERNEL_ISA == 2
      const std::size_t blk = k0 / kLanes;
      if (soft_block_[blk] || soft_block_[blk + 1]) {
        block(k0, std::integral_constant<std::size_t, kVec>{});
        block(k0 + kVec, std::integral_constant<std::size_t, kVec>{});
        return;
      }
      const FrameLanes<d8> F = load_frame<d8>(&frame_[blk * kFrameBlock], kFrameBlock);
      const std::size_t i = 3 * k0;
      const double *p1 = &x1[i], *px = &x[i], *pold = old ? &x_old[i] : px;
      double* pg = &g1[i];
      contacts(k0, 2 * kVec, p1, px, pold, pg, F);
      if (ahead)
        trial_block(p1, px, pg, ahead_old ? &next.gx[i] : pg, next.momentum, next.step, F,
                    &metric_[blk * kMetricBlock], kMetricBlock, &next.x2[i], sums);
#endif
    };
    for_vectors(begin, end, pair, block);
    part.here.dnd = lane_sum(d_g1);
    part.here.res_sum = lane_sum(res2);
    part.ahead = {lane_sum(sums.dd), -lane_sum(sums.d_gy), lane_sum(sums.uphill)};
  };
  const Parts total = reduce_chunks<Parts>(nc, pass);
  t += total.here;
  TrialSums t_next = total.ahead;
  gather_rows(dv_, dw_, true, g1);
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    const std::size_t i = 3 * nc + j;
    const double y = old ? mo.ca * x[i] - mo.cb * x_old[i] : x[i];
    const double res = (x1[i] - std::clamp(x1[i] - s_res * g1[i], rows_[j].lo, rows_[j].hi)) * inv_s;
    t.dnd += (x1[i] - y) * g1[i];
    t.res_sum += res * res;
  }
  if (ahead) {
    for (std::size_t j = 0; j < rows_.size(); ++j) {
      const std::size_t i = 3 * nc + j;
      trial_row(x1[i], ahead_old ? x[i] : 0.0, g1[i], ahead_old ? next.gx[i] : 0.0, next.momentum,
                next.step, row_metric_[j], rows_[j].lo, rows_[j].hi, next.x2[i], t_next);
    }
  }
  return t_next;
}

constexpr Isa kIsa = static_cast<Isa>(CES_KERNEL_ISA);
template void CcpProblem::scatter_bodies_on<kIsa>(const double*, ConstSpan, bool,
                                                  std::vector<Vec3>&, std::vector<Vec3>&,
                                                  const std::vector<std::uint32_t>*) const;
template CcpProblem::TrialSums CcpProblem::apgd_step_on<kIsa>(ConstSpan, ConstSpan, Span,
                                                              ConstSpan, ConstSpan, Momentum,
                                                              double) const;
template CcpProblem::TrialSums CcpProblem::apgd_gradient_on<kIsa>(ConstSpan, Span, ConstSpan,
                                                                  ConstSpan, Momentum, TrialSums&,
                                                                  const NextTrial&) const;

#pragma GCC pop_options

}  // namespace ces
