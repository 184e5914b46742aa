// The APGD kernel (CcpProblem::apgd_step, apgd_gradient and the bodies'
// pass, scatter_bodies): four contacts to a vector (GCC/Clang vector
// extensions; one AVX instruction each where the instruction set has it,
// two SSE2 halves otherwise). kernel_baseline.cpp, kernel_avx2.cpp and
// kernel_avx512.cpp each include it once, with CES_KERNEL_ISA naming their
// instruction set; the code below runs beyond baseline x86-64 only in
// those (isa.hpp chooses among them). Lane l holds contact 4 b + l of
// block b.
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
[[gnu::always_inline]] inline d4 select(decltype(d4{} < d4{}) mask, d4 a, d4 b) { return mask ? a : b; }
[[gnu::always_inline]] inline d4 vmax(d4 a, d4 b) { return select(a < b, b, a); }  // std::max(a, b)'s lanes
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

// The x, y, z rows of four contacts, lane = contact.
struct Lanes3 {
  d4 c[3];
};
// 12 doubles [x0 y0 z0 x1 y1 z1 ...], as three vectors a, <-> the lanes.
[[gnu::always_inline]] inline Lanes3 lanes_of(const d4 a[3]) {
  const d4 x01 = __builtin_shufflevector(a[0], a[1], 0, 3, 6, 7);
  const d4 y01 = __builtin_shufflevector(a[0], a[1], 1, 4, 7, 7);
  const d4 z01 = __builtin_shufflevector(a[0], a[1], 2, 5, 5, 5);
  return {{__builtin_shufflevector(x01, a[2], 0, 1, 2, 5),
           __builtin_shufflevector(y01, a[2], 0, 1, 2, 6),
           __builtin_shufflevector(z01, a[2], 0, 1, 4, 7)}};
}
[[gnu::always_inline]] inline void rows_of(const Lanes3& r, d4 a[3]) {
  const d4 &x = r.c[0], &y = r.c[1], &z = r.c[2];
  a[0] = __builtin_shufflevector(__builtin_shufflevector(x, y, 0, 4, 1, 1), z, 0, 1, 4, 2);
  a[1] = __builtin_shufflevector(__builtin_shufflevector(y, z, 1, 5, 2, 2), x, 0, 1, 6, 2);
  a[2] = __builtin_shufflevector(__builtin_shufflevector(z, x, 2, 7, 3, 3), y, 0, 1, 7, 2);
}
[[gnu::always_inline]] inline Lanes3 load_rows(const double* p) {
  const d4 a[3] = {load(p), load(p + 4), load(p + 8)};
  return lanes_of(a);
}
[[gnu::always_inline]] inline void store_rows(double* p, const Lanes3& r) {
  d4 a[3];
  rows_of(r, a);
  for (std::size_t j = 0; j < 3; ++j) store(p + 4 * j, a[j]);
}

using mask4 = decltype(d4{} < d4{});

[[gnu::always_inline]] inline bool all_lanes(mask4 m) {
#if defined(__AVX__)
  return _mm256_movemask_pd(__m256d(m)) == 0xf;
#else
  return (m[0] & m[1] & m[2] & m[3]) != 0;
#endif
}

// A block's normals and friction coefficients, lane = contact.
struct FrameLanes {
  d4 n[3], mu;
};
[[gnu::always_inline]] inline FrameLanes load_frame(const StoredScalar* f) {
  return {{widen(f), widen(f + kVec), widen(f + 2 * kVec)}, widen(f + 3 * kVec)};
}

// project_cone's cases on world rows, lane by lane: P = Π(z) onto
// |P - n (n.P)| <= mu n.P. A sticking contact keeps z as it is. The sliding
// case's square root and division are slow (tens of cycles, not pipelined),
// so a block none of whose lanes slides, most of a flow's blocks, skips
// them.
[[gnu::always_inline]] inline void project_cone(const FrameLanes& F, Lanes3& z) {
  const d4* n = F.n;
  const d4 zn = n[0] * z.c[0] + n[1] * z.c[1] + n[2] * z.c[2];
  const d4 t[3] = {z.c[0] - n[0] * zn, z.c[1] - n[1] * zn, z.c[2] - n[2] * zn};
  const d4 s2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2], mu = F.mu, mu2 = mu * mu;
  const auto inside = (zn >= 0.0) & (s2 <= mu2 * zn * zn);
  const auto polar = (zn <= 0.0) & (mu2 * s2 <= zn * zn);
  const d4 zero = {}, pressing = vmax(zn, zero);  // a frictionless lane's normal part
  const auto frictionless = mu <= 0.0;
  const auto keep = ~frictionless & inside, clear = ~frictionless & ~inside & polar;
  if (all_lanes(keep | clear | frictionless)) {
    for (auto& c : z.c) c = select(keep, c, zero);
    for (int c = 0; c < 3; ++c) z.c[c] = select(frictionless, n[c] * pressing, z.c[c]);
    return;
  }
  const d4 s = vsqrt(s2);
  const d4 along = mu * s + zn, q = 1.0 / ((mu2 + 1.0) * s);
  const d4 pn = select(frictionless, pressing, along * s * q), scale = mu * along * q;
  for (int c = 0; c < 3; ++c) {
    const d4 slid = n[c] * pn + select(frictionless, zero, t[c] * scale);
    z.c[c] = select(keep, z.c[c], select(clear, zero, slid));
  }
}

// One number per contact (lane = contact) spread over a block's 12 rows,
// three to a contact, as load_rows finds them: [c0 c0 c0 c1] [c1 c1 c2 c2]
// [c2 c3 c3 c3].
[[gnu::always_inline]] inline void spread_lanes(d4 c, d4 out[3]) {
  out[0] = __builtin_shufflevector(c, c, 0, 0, 0, 1);
  out[1] = __builtin_shufflevector(c, c, 1, 1, 2, 2);
  out[2] = __builtin_shufflevector(c, c, 2, 3, 3, 3);
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

// Lane sums of a trial's dd, d.gy and uphill (CcpProblem::TrialSums).
struct TrialLanes {
  d4 dd = {}, d_gy = {}, uphill = {};
};

// One block of a trial (apgd_step): x1 = Π(y - step gy) into p1, with y =
// ca x - cb x_old and gy = ca gx - cb g_old (pold, pgold unread when cb =
// 0); adds its sums to `sums`.
[[gnu::always_inline]] inline void trial_block(const double* px, const double* pold,
                                               const double* pgx, const double* pgold,
                                               CcpProblem::Momentum mo, double step,
                                               const FrameLanes& F, const float* metric,
                                               double* p1, TrialLanes& sums) {
  // The contacts' steps and the weights of |d|^2 (CcpProblem::metric_),
  // spread over the rows: a row vector holds a contact's rows and the next's.
  d4 st[3], wd[3];
  spread_lanes(step * widen(metric), st);
  spread_lanes(widen(metric + kVec), wd);
  // In registers throughout: the rows transposed to lanes and back.
  d4 y[3], gy[3], z[3];
  for (std::size_t j = 0; j < 3; ++j) {
    y[j] = load(px + 4 * j);
    gy[j] = load(pgx + 4 * j);
    if (mo.cb != 0.0) {
      y[j] = mo.ca * y[j] - mo.cb * load(pold + 4 * j);
      gy[j] = mo.ca * gy[j] - mo.cb * load(pgold + 4 * j);
    }
    z[j] = y[j] - st[j] * gy[j];
  }
  Lanes3 r = lanes_of(z);
  project_cone(F, r);
  d4 x1[3];
  rows_of(r, x1);
  for (std::size_t j = 0; j < 3; ++j) {
    store(p1 + 4 * j, x1[j]);
    const d4 v1 = x1[j], d = v1 - y[j];
    sums.dd += wd[j] * d * d;
    sums.d_gy += d * gy[j];
    sums.uphill += gy[j] * (v1 - load(px + 4 * j));
  }
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

// g = J dv + b n of a block's contacts (world rows): count (<= 4) contacts
// from a, b (body indices), frame F, lever arms and bias; lane = contact,
// lanes past count zero.
[[gnu::always_inline]] inline Lanes3 gather_block(const FrameLanes& F, const StoredScalar* lever,
                                                  const std::int32_t* a, const std::int32_t* b,
                                                  std::size_t count, const std::vector<Vec3>& dv,
                                                  const std::vector<Vec3>& dw, const double* bias) {
  std::size_t ia[kVec], ib[kVec];
  for (std::size_t l = 0; l < kVec; ++l) {
    ia[l] = std::size_t(a[std::min(l, count - 1)]);
    ib[l] = std::size_t(b[std::min(l, count - 1)]);
  }
  // Four bodies' velocities as x, y, z lanes: each loaded as one vector
  // (its fourth number the next body's, unused; dv, dw have a spare) and
  // transposed, 11 instructions where gathering lane by lane takes 16.
  auto lanes = [&](const std::vector<Vec3>& v, const std::size_t* i, d4 out[3]) {
    const d4 r0 = load(v[i[0]].data()), r1 = load(v[i[1]].data()), r2 = load(v[i[2]].data()),
             r3 = load(v[i[3]].data());
    const d4 xz01 = __builtin_shufflevector(r0, r1, 0, 4, 2, 6);
    const d4 y01 = __builtin_shufflevector(r0, r1, 1, 5, 3, 7);
    const d4 xz23 = __builtin_shufflevector(r2, r3, 0, 4, 2, 6);
    const d4 y23 = __builtin_shufflevector(r2, r3, 1, 5, 3, 7);
    out[0] = __builtin_shufflevector(xz01, xz23, 0, 1, 4, 5);
    out[1] = __builtin_shufflevector(y01, y23, 0, 1, 4, 5);
    out[2] = __builtin_shufflevector(xz01, xz23, 2, 3, 6, 7);
  };
  // Relative velocity at the contact points, component by component.
  d4 va[3], wa[3], vb[3], wb[3];
  lanes(dv, ia, va);
  lanes(dw, ia, wa);
  lanes(dv, ib, vb);
  lanes(dw, ib, wb);
  d4 ra[3], rb[3];
  levers(lever, ra, rb);
  const d4 b_n = load(bias);
  Lanes3 g;
  for (int c = 0; c < 3; ++c) {
    const int c1 = (c + 1) % 3, c2 = (c + 2) % 3;  // w x r, as Eigen's cross
    const d4 rel = (vb[c] + (wb[c1] * rb[c2] - wb[c2] * rb[c1])) -
                   (va[c] + (wa[c1] * ra[c2] - wa[c2] * ra[c1]));
    g.c[c] = rel + b_n * F.n[c];
  }
  if (count < kVec) {  // padding lanes: zero, whatever the velocities
    const d4 lane = {0.0, 1.0, 2.0, 3.0};
    const auto valid = lane < double(count);
    for (auto& c : g.c) c = select(valid, c, d4{});
  }
  return g;
}

// g += eps (n.P) n, a yielding contact's spring (CcpProblem::softness), lane
// by lane; eps is 0 on a rigid lane.
[[gnu::always_inline]] inline void add_spring(const FrameLanes& F, d4 eps, const Lanes3& P,
                                       Lanes3& g) {
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
    for_blocks(begin, end, [&](std::size_t k0, auto count) __attribute__((always_inline)) {
      BlockRows blk(3 * k0, 3 * count);
      const double *px = blk.in(x, 0), *pgx = blk.in(gx, 1);
      const double *pold = old ? blk.in(x_old, 2) : px, *pgold = old ? blk.in(g_old, 3) : pgx;
      double* p1 = blk.out(x1, 4);
      trial_block(px, pold, pgx, pgold, mo, step, load_frame(&frame_[k0 / kLanes * kFrameBlock]),
                  &metric_[k0 / kLanes * kMetricBlock], p1, sums);
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
    for_blocks(begin, end, [&](std::size_t k0, auto count) __attribute__((always_inline)) {
      BlockRows blk(3 * k0, 3 * count);
      const FrameLanes F = load_frame(&frame_[k0 / kLanes * kFrameBlock]);
      const double *p1 = blk.in(x1, 0), *px = blk.in(x, 1), *pold = old ? blk.in(x_old, 2) : px;
      Lanes3 g = gather_block(F, &lever_[6 * k0], &a_[k0], &b_[k0], count, dv_, dw_, &bias_[k0]);
      if (soft_block_[k0 / kLanes]) add_spring(F, load(&softness_[k0]), load_rows(p1), g);
      double* pg = blk.out(g1, 3);
      store_rows(pg, g);
      blk.flush(g1, 3);
      // d.g1 with d = x1 - y, y made again as apgd_step made it (the same
      // bits): cheaper than storing y there and reading it here.
      for (std::size_t j = 0; j < 12; j += 4) {
        const d4 y = old ? mo.ca * load(px + j) - mo.cb * load(pold + j) : load(px + j);
        d_g1 += (load(p1 + j) - y) * load(pg + j);
      }
      const Lanes3 r1 = load_rows(p1);
      Lanes3 q;
      for (int c = 0; c < 3; ++c) q.c[c] = r1.c[c] - s_res * g.c[c];
      project_cone(F, q);
      for (int c = 0; c < 3; ++c) {
        const d4 res = (r1.c[c] - q.c[c]) * inv_s;
        res2 += res * res;
      }
      if (ahead) {  // x1 is the next trial's x, x its x_old, g1 its gx
        const double* pgold = ahead_old ? blk.in(next.gx, 4) : pg;
        trial_block(p1, px, pg, pgold, next.momentum, next.step, F,
                    &metric_[k0 / kLanes * kMetricBlock], blk.out(next.x2, 5), sums);
        blk.flush(next.x2, 5);
      }
    });
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
