// Engine checks of the contact solvers: the cone projection, the APGD
// kernel and metric against plain operations and eigenvalues, non-finite
// residuals, and APGD against SPG and projected Gauss-Seidel. Each test
// states its tolerance.
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "dynamics/ccp.hpp"
#include "engine_support.hpp"
#include "sim/world.hpp"
#include "support.hpp"

namespace ces {
namespace {

using test::base_model;
using test::material_name;
using test::Uniform;

// ---------------------------------------------------------------- solvers

// Moreau's decomposition: x = Π_K(x) + Π_K°(x) with the two parts
// orthogonal, for the friction cone K and its polar K° = {mu |t| <= -n}.
// 1e5 random points over all four cases. Tolerance 1e-12 relative.
TEST(Engine, ConeProjectionIsMoreauDecomposition) {
  Uniform uniform{7};
  for (int i = 0; i < 100000; ++i) {
    const double mu = i % 10 == 0 ? 0.0 : 1.5 * (uniform() + 1.0) / 2.0;
    const Vec3 x(uniform(), uniform(), uniform());
    Vec3 p = x;
    project_cone(mu, p[0], p[1], p[2]);
    const Vec3 d = x - p;
    const double tol = 1e-12 * x.norm();
    ASSERT_LE(std::hypot(p[1], p[2]), mu * p[0] + tol) << "outside the cone";
    ASSERT_LE(mu * std::hypot(d[1], d[2]), -d[0] + tol) << "remainder outside the polar cone";
    ASSERT_NEAR(p.dot(d), 0.0, tol * x.norm()) << "parts not orthogonal";
  }
}

// The APGD kernel (CcpProblem::apgd_step, apgd_gradient: four contacts to a
// SIMD vector, the last block padded, on world rows) against the plain row
// operations in contact frames, through to_local and to_world, on a random
// problem: 4 bodies (one a wall), 13 contacts at random points and normals
// (lever arms off the normal, so every term of the Jacobian counts; two
// normals along -z and +z, where a tangent basis is most easily wrong),
// friction 0 on some, two yielding, and one bilateral row. The normals are stored in
// float, so the frame is orthonormal to about 1e-7: the tolerance is 1e-6
// of each quantity's scale. A wrong sign, term or case is of order 1.
TEST(Engine, ApgdKernelMatchesPlainOperations) {
  Uniform uniform{11};
  auto vec = [&] { return Vec3(uniform(), uniform(), uniform()); };
  SolverBodies B;
  B.resize(4);
  for (std::size_t i = 0; i < 4; ++i) {
    B.x[i] = 0.01 * vec();
    B.v[i] = B.v_free[i] = vec();
    B.w[i] = B.w_free[i] = 10.0 * vec();
    B.inv_mass[i] = i == 3 ? 0.0 : 1e3 * (1.5 + uniform());
    const Vec3 d = 1e7 * (Vec3::Constant(1.5) + 0.5 * vec());
    B.inv_inertia[i] = i == 3 ? Mat3::Zero() : Mat3(d.asDiagonal());
  }
  // A material per contact, each contact between two surfaces of it.
  // Contacts 1 and 6 yield (their blocks of four take the spring's term),
  // the blocks from 8 on are rigid.
  std::vector<Material> materials;
  for (int k = 0; k < 13; ++k) {
    const double friction = k % 5 == 0 ? 0.0 : 0.5 + 0.4 * uniform();
    const double compliance = k == 1 || k == 6 ? 0.5e-3 : 0.0;
    materials.push_back({std::string("m").append(std::to_string(k)), 1000.0, friction, 0.0, compliance});
  }
  const MaterialTable table(materials, {});
  Contacts c;
  for (int k = 0; k < 13; ++k) {
    const int a = k % 3, b = k % 4 == 3 ? 3 : (a + 1 + k % 2) % 3;
    const Vec3 n = k == 11   ? Vec3(0, 0, -1)
                   : k == 12 ? Vec3(1e-5, 0, 1).normalized()
                             : vec().normalized();
    c.push(a, b, n, 0.01 * vec(), 1e-4 * uniform(), 0.001, table.pair_index(k, k), ContactKey{});
  }
  BilateralRow row;
  row.a = 0;
  row.lin_a = vec();
  row.ang_a = 0.01 * vec();
  row.bias = 0.1;
  CcpProblem p;
  p.assemble(c, table, B, {row}, 1e-3, ContactSettings{});
  const std::size_t m = p.row_count();
  ASSERT_EQ(m, 40u);
  // World rows, each with a spare past its end (RowBuffer::take).
  auto rows = [&] { return std::vector<double>(m + 1); };
  std::vector<double> x = rows(), x_old = rows(), x1 = rows(), gx = rows(), g_old = rows(),
                      g1 = rows(), y = rows(), gy = rows();
  for (std::size_t i = 0; i < m; ++i) {
    x[i] = uniform();
    x_old[i] = uniform();
    gx[i] = uniform();
    g_old[i] = uniform();
  }
  auto span = [&](std::vector<double>& v) { return Span(v.data(), m); };
  auto cspan = [&](const std::vector<double>& v) { return ConstSpan(v.data(), m); };
  auto scale_of = [&](const std::vector<double>& v) {
    double s = 0.0;
    for (std::size_t i = 0; i < m; ++i) s = std::max(s, std::abs(v[i]));
    return s;
  };
  // The reference: Π(y - step W gy) row by row in contact frames, in world
  // rows (a contact's weight is the same on its three rows, so W commutes
  // with the change of frame).
  auto plain_step = [&](const std::vector<double>& yw, const std::vector<double>& gw, double step) {
    std::vector<double> yl(m), gl(m), out(m), world = rows(), wg = rows();
    for (std::size_t i = 0; i < m; ++i) wg[i] = p.metric_weight(i) * gw[i];
    p.to_local(cspan(yw), yl);
    p.to_local(cspan(wg), gl);
    p.projected_step(yl, gl, step, out);
    p.to_world(out, span(world));
    return world;
  };
  auto expect_rows_near = [&](const std::vector<double>& got, const std::vector<double>& want) {
    const double tol = 1e-6 * std::max(scale_of(want), 1e-300);
    for (std::size_t i = 0; i < m; ++i) ASSERT_NEAR(got[i], want[i], tol) << i;
  };
  const double step = 0.3, ca = 1.7, cb = 0.7;
  for (std::size_t i = 0; i < m; ++i) {
    y[i] = ca * x[i] - cb * x_old[i];
    gy[i] = ca * gx[i] - cb * g_old[i];
  }
  const CcpProblem::Momentum momentum{ca, cb};
  CcpProblem::TrialSums t = p.apgd_step(x, x_old, span(x1), gx, g_old, momentum, step);
  expect_rows_near(x1, plain_step(y, gy, step));
  const CcpProblem::TrialSums t_trial = t;
  p.apgd_gradient(x1, span(g1), x, x_old, momentum, t, {});
  // The next trial made in the gradient's pass (solve_apgd's guess that x1
  // is accepted) is apgd_step's from x1, x, g1, gx to the bit, with and
  // without momentum, and the pass's own sums do not change.
  for (const CcpProblem::Momentum next : {CcpProblem::Momentum{1.4, 0.4}, CcpProblem::Momentum{}}) {
    std::vector<double> x2 = rows(), x2_step = rows(), g1_again = rows();
    CcpProblem::TrialSums t_again = t_trial;
    const CcpProblem::TrialSums ahead = p.apgd_gradient(
        x1, span(g1_again), x, x_old, momentum, t_again, {span(x2), cspan(gx), next, 0.2});
    const CcpProblem::TrialSums alone = p.apgd_step(x1, x, span(x2_step), g1, gx, next, 0.2);
    EXPECT_EQ(x2, x2_step);
    EXPECT_EQ(g1_again, g1);
    EXPECT_EQ(ahead.dd, alone.dd);
    EXPECT_EQ(ahead.dnd, alone.dnd);
    EXPECT_EQ(ahead.uphill, alone.uphill);
    EXPECT_EQ(t_again.dnd, t.dnd);
    EXPECT_EQ(t_again.res_sum, t.res_sum);
    EXPECT_GT(ahead.dd, 0.0);
  }
  // The gradient at x1 by the plain scatter and gather, in world rows.
  std::vector<double> x1_local(m), g_local(m), g = rows();
  p.to_local(cspan(x1), x1_local);
  p.gradient(x1_local, g_local);
  p.to_world(g_local, span(g));
  expect_rows_near(g1, g);
  // The sums, row by row; the residual from the plain residual(): a
  // contact's residual is a vector, its length the same in any frame.
  double dd = 0, dnd = 0, uphill = 0;
  for (std::size_t i = 0; i < m; ++i) {
    const double d = x1[i] - y[i];
    dd += d * d / p.metric_weight(i);
    dnd += d * (g[i] - gy[i]);
    uphill += gy[i] * (x1[i] - x[i]);
  }
  const double rms = p.residual(x1_local, g_local);
  EXPECT_NEAR(t.dd, dd, 1e-6 * dd);
  EXPECT_NEAR(t.dnd, dnd, 1e-6 * std::abs(dnd));
  EXPECT_NEAR(t.uphill, uphill, 1e-6 * std::abs(uphill));
  EXPECT_NEAR(std::sqrt(t.res_sum / double(m)), rms, 1e-6 * rms);
  EXPECT_GT(dd * std::abs(dnd) * rms, 0.0);  // nothing trivially zero
  // world_gradient: the same gradient at x1, without the kernel.
  std::vector<double> gw = rows();
  p.world_gradient(cspan(x1), span(gw));
  expect_rows_near(gw, g);
  // Without momentum y = x, gy = gx, and x_old, g_old are not read.
  const std::vector<double> nan(m + 1, std::numeric_limits<double>::quiet_NaN());
  t = p.apgd_step(x, cspan(nan), span(x1), gx, cspan(nan), {}, step);
  expect_rows_near(x1, plain_step(x, gx, step));
  p.apgd_gradient(x1, span(g1), x, cspan(nan), {}, t, {});
  EXPECT_TRUE(std::isfinite(t.dd + t.dnd + t.uphill + t.res_sum));
  // Blocks none of whose contacts slides (each sticks, separates or is
  // frictionless) take the projection's short path: a sticking contact
  // keeps its impulse to the bit, a separating one goes to zero.
  std::vector<double> zero = rows(), local(m);
  for (std::size_t k = 0; 3 * k < m - 1; ++k) {
    local[3 * k] = k % 3 == 0 ? -1.0 : 1.0;  // friction >= 0.1: |x_t| <= 0.071 sticks
    local[3 * k + 1] = 0.05 * uniform();
    local[3 * k + 2] = 0.05 * uniform();
  }
  p.to_world(local, span(x));
  t = p.apgd_step(x, cspan(nan), span(x1), zero, cspan(nan), {}, step);
  expect_rows_near(x1, plain_step(x, zero, step));
  int kept = 0, cleared = 0;
  for (std::size_t k = 0; 3 * k < m - 1; ++k) {
    const bool same =
        x1[3 * k] == x[3 * k] && x1[3 * k + 1] == x[3 * k + 1] && x1[3 * k + 2] == x[3 * k + 2];
    const bool none = x1[3 * k] == 0.0 && x1[3 * k + 1] == 0.0 && x1[3 * k + 2] == 0.0;
    kept += same;
    cleared += none;
  }
  EXPECT_GT(kept, 3);
  EXPECT_GT(cleared, 2);  // the separating ones (the frictionless pressing keep only their normal)
}

// A 10-layer stack (3 x 3 spheres per layer) solved from rest without warm
// start: APGD needs fewer iterations than projected Gauss-Seidel to reach the
// same residual tolerance. Counts, not times.
int stack_iterations(SolverMethod method) {
  auto m = base_model({0.3});
  m->bodies.push_back(test::ground_plane());
  m->solver.method = method;
  m->solver.max_iterations = 5000;
  m->solver.tolerance = 1e-5;
  m->solver.warm_start = false;
  World w(m);
  const double r = 0.005;
  for (int layer = 0; layer < 10; ++layer)
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k)
        w.add_particle(0, r, 0, Vec3(2 * r * i, r + 2 * r * layer, 2 * r * k));
  const StepStats& s = w.step();
  EXPECT_TRUE(s.solver.converged);
  return s.solver.iterations;
}

// A contact problem with a NaN in it (the spin of a dynamic box a sphere
// rests on; a NaN on the particle would leave it without contacts, its
// envelope being NaN): every solver reports a NaN residual and no
// convergence, never 0, which would claim a residual no iterate had.
TEST(Engine, SolversReportNonFiniteResidual) {
  for (const SolverMethod method : {SolverMethod::APGD, SolverMethod::SPG, SolverMethod::PGS}) {
    auto m = base_model();
    RigidBody box;
    box.kind = BodyKind::Dynamic;
    box.shape = geo::Box{Vec3(0.05, 0.01, 0.05)};
    box.pose.position = Vec3(0, -0.01, 0);
    box.mass = 1.0;
    m->bodies.push_back(box);
    m->solver.method = method;
    World w(m);
    const double r = 0.005;
    w.add_particle(0, r, 0, Vec3(0, r, 0));
    w.bodies().angular_velocity[0] = Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0);
    const StepStats& s = w.step();
    EXPECT_GE(s.contacts, 1u) << int(method);
    EXPECT_TRUE(std::isnan(s.solver.residual)) << int(method) << ": " << s.solver.residual;
    EXPECT_FALSE(s.solver.converged) << int(method);
  }
}

// APGD's metric (solve_apgd) gives each contact a step scaled to its own
// block of N, so decoupled contacts converge alike whatever their masses:
// 25 spheres at rest on the ground, densities 10 to 1e5 kg/m^3, one step
// from a cold start to 1e-8 m/s within 40 iterations (the test records
// its count). One step for all, set by the lightest, would move the
// heaviest contacts' impulses 1e4 times too slowly.
TEST(Engine, ApgdConvergesAlikeAcrossMassRatios) {
  auto m = base_model();
  std::vector<Material> mats;
  for (int i = 0; i < 5; ++i)
    mats.push_back({material_name(i), std::pow(10.0, 1 + i), 0.5, 0.0});
  m->materials = MaterialTable(mats, {});
  m->bodies.push_back(test::ground_plane());
  m->solver.warm_start = false;
  m->solver.tolerance = 1e-8;
  World w(m);
  const double r = 0.002;
  for (int i = 0; i < 25; ++i) w.add_particle(0, r, i % 5, Vec3(3 * r * i, r, 0));
  const StepStats& s = w.step();
  ASSERT_EQ(s.contacts, 25u);
  EXPECT_TRUE(s.solver.converged);
  EXPECT_LE(s.solver.iterations, 40);
  RecordProperty("iterations", s.solver.iterations);
}

// The metric's weight is 1 / (a bound on the largest eigenvalue of the
// contact's 3x3 block of N in world rows, sum over its bodies of
// m^-1 1 + [r]x I^-1 [r]x^T): checked against the block's eigenvalues,
// computed here, for random anisotropic bodies (a bound; float rounding:
// 1e-6), and equal to them for spheres, where the bound is exact.
TEST(Engine, ApgdMetricBoundsEachContactBlock) {
  Uniform uniform{5};
  auto vec = [&] { return Vec3(uniform(), uniform(), uniform()); };
  SolverBodies B;
  B.resize(5);
  for (std::size_t i = 0; i < 5; ++i) {
    B.x[i] = 0.01 * vec();
    B.inv_mass[i] = i == 4 ? 0.0 : 1e3 * (1.5 + uniform());
    const Mat3 R = Quat(uniform(), uniform(), uniform(), uniform()).normalized().toRotationMatrix();
    const Vec3 d = i < 2 ? Vec3(Vec3::Constant(2e7)) : Vec3(1e7 * (Vec3::Constant(1.5) + vec()));
    B.inv_inertia[i] = i == 4 ? Mat3::Zero() : Mat3(R * d.asDiagonal() * R.transpose());
  }
  const MaterialTable table({{"m", 1000.0, 0.5, 0.0}}, {});
  Contacts c;
  for (int k = 0; k < 20; ++k) {
    const int a = k % 4, b = k % 3 == 0 ? 4 : (a + 1) % 4;
    c.push(a, b, vec().normalized(), 0.01 * vec(), 0.0, 0.001, table.pair_index(0, 0),
           ContactKey{});
  }
  CcpProblem p;
  p.assemble(c, table, B, {}, 1e-3, ContactSettings{});
  auto part = [&](int body, const Vec3& r) -> Mat3 {
    const auto u = std::size_t(body);
    Mat3 rx;
    rx << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
    return B.inv_mass[u] * Mat3::Identity() + rx * B.inv_inertia[u] * rx.transpose();
  };
  for (std::size_t k = 0; k < c.size(); ++k) {
    const int a = c.body_a[k], b = c.body_b[k];
    const Mat3 block =
        part(a, c.point[k] - B.x[std::size_t(a)]) + part(b, c.point[k] - B.x[std::size_t(b)]);
    const double lambda = Eigen::SelfAdjointEigenSolver<Mat3>(block).eigenvalues().maxCoeff();
    const double bound = 1.0 / p.metric_weight(3 * k);
    EXPECT_LE(lambda, bound * (1.0 + 1e-6)) << k;
    if (a < 2 && (b < 2 || b == 4)) {  // spheres
      EXPECT_NEAR(bound, lambda, 1e-6 * lambda) << k;
    }
    EXPECT_EQ(p.metric_weight(3 * k), p.metric_weight(3 * k + 2));
  }
}

TEST(Engine, ApgdBeatsGaussSeidelOnStack) {
  const int apgd = stack_iterations(SolverMethod::APGD);
  const int pgs = stack_iterations(SolverMethod::PGS);
  const int spg = stack_iterations(SolverMethod::SPG);
  RecordProperty("apgd", apgd);
  RecordProperty("pgs", pgs);
  RecordProperty("spg", spg);
  EXPECT_LT(apgd, pgs);
}

}  // namespace
}  // namespace ces
