// Engine checks of the parallel step: bitwise identical results across
// runs and thread counts, the parallel helpers against their serial
// definitions, the contact adjacency, and the spatial reorder with the warm
// start across it. Each test states its tolerance.
#include <gtest/gtest.h>
#include <omp.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <memory>
#include <thread>

#include "common/parallel.hpp"
#include "dynamics/adjacency.hpp"
#include "engine_support.hpp"
#include "sim/world.hpp"
#include "support.hpp"

namespace ces {
namespace {

using test::base_model;

// ---------------------------------------------------------------- determinism

std::vector<double> pile_state(int threads) {
  omp_set_num_threads(threads);
  auto m = base_model({0.4});
  m->solver.max_iterations = 50;
  m->solver.tolerance = 1e-8;
  m->bodies.push_back(test::ground_plane());
  for (const Vec3& n : {Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 0, 1), Vec3(0, 0, -1)}) {
    RigidBody wall = test::ground_plane(n);
    wall.shape = geo::Plane{n, -0.03};
    m->bodies.push_back(wall);
  }
  World w(m);
  const double r = 0.002;
  int count = 0;
  for (int layer = 0; count < 500; ++layer)
    for (int i = 0; i < 10 && count < 500; ++i)
      for (int k = 0; k < 10 && count < 500; ++k, ++count)
        w.add_particle(0, r * (1.0 + 0.1 * ((i + k + layer) % 3)), 0,
                       Vec3(-0.025 + 0.0052 * i + 0.0003 * (layer % 2), r + 0.0055 * layer,
                            -0.025 + 0.0052 * k));
  for (int i = 0; i < 1000; ++i) w.step();
  std::vector<double> state;
  const Particles& p = w.particles();
  for (std::size_t i = 0; i < p.size(); ++i)
    for (const Vec3* v : {&p.position[i], &p.velocity[i], &p.angular_velocity[i]})
      state.insert(state.end(), v->data(), v->data() + 3);
  omp_set_num_threads(omp_get_num_procs());
  return state;
}

TEST(Engine, PileIsBitwiseIdenticalAcrossRunsAndThreads) {
  const auto a = pile_state(1), b = pile_state(1), c = pile_state(2);
  ASSERT_EQ(a.size(), c.size());
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(double)));
  EXPECT_EQ(0, std::memcmp(a.data(), c.data(), a.size() * sizeof(double)));
}

// for_each_chunk (common/parallel.hpp), which the solver's passes run on:
// every chunk runs exactly once on 1 to 3 threads, and when one thread is
// slow (it sleeps 1 ms in each of its chunks) the others take over what is
// left of its share. A static schedule leaves it its whole share (500 of
// 1000 chunks at 2 threads): here it keeps a few, and fewer than half
// unless the fast thread is kept off its core for 250 ms.
TEST(Engine, EveryChunkRunsOnceAndASlowThreadsShareIsTakenOver) {
  constexpr std::size_t kChunks = 1000;
  for (const int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    std::vector<std::atomic<int>> runs(kChunks);
    std::atomic<std::size_t> slow_ran{0};
    for_each_chunk(kChunks, true, [&](std::size_t c) {
      runs[c].fetch_add(1);
      if (threads > 1 && omp_get_thread_num() == 1) {
        slow_ran.fetch_add(1);
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    });
    for (std::size_t c = 0; c < kChunks; ++c) ASSERT_EQ(runs[c].load(), 1) << c << ", " << threads;
    if (threads > 1) {
      EXPECT_LT(slow_ran.load(), kChunks / threads / 2) << threads << " threads";
    }
  }
  omp_set_num_threads(omp_get_num_procs());
}

// The helpers the step's parallel passes run on (common/parallel.hpp),
// against their serial definitions, on 1 to 3 threads and on sizes that
// are and are not whole blocks.
TEST(Engine, ParallelScanSelectAndRunChunksMatchTheirSerialDefinitions) {
  for (const int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    for (const std::size_t n : {std::size_t(0), std::size_t(5), std::size_t(4096), std::size_t(30001)}) {
      std::vector<std::uint64_t> v(n), expected(n);
      std::uint64_t sum = 0;
      for (std::size_t i = 0; i < n; ++i) {
        v[i] = (i * 7919) % 13;
        expected[i] = sum;
        sum += v[i];
      }
      exclusive_scan(v);
      EXPECT_EQ(v, expected) << n << " items, " << threads << " threads";
      std::vector<std::uint32_t> picked, serial;
      auto keep = [](std::size_t i) { return i % 3 == 0 || i % 7 == 1; };
      for (std::size_t i = 0; i < n; ++i)
        if (keep(i)) serial.push_back(std::uint32_t(i));
      select_in_order(n, keep, picked);
      EXPECT_EQ(picked, serial) << n << " items, " << threads << " threads";
      // Runs of 1 to 9 equal labels: each item once, each run in one chunk.
      std::vector<std::size_t> label(n);
      for (std::size_t i = 1; i < n; ++i) label[i] = label[i - 1] + (i % 9 == (i / 9) % 9);
      std::vector<std::atomic<int>> seen(n);
      std::vector<std::atomic<std::size_t>> chunk_of(n + 1);
      auto same = [&](std::size_t a, std::size_t b) { return label[a] == label[b]; };
      for_each_run_chunk(n, 100, same, [&](std::size_t begin, std::size_t end) {
        for (std::size_t i = begin; i < end; ++i) {
          seen[i].fetch_add(1);
          chunk_of[label[i]].store(begin);
        }
      });
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_EQ(seen[i].load(), 1) << i;
        if (i > 0 && same(i - 1, i)) {
          ASSERT_LE(chunk_of[label[i]].load(), i - 1) << "run cut at " << i;
        }
      }
      // Fixed ranges: chunk c is [100 c, 100 c + 100), the last one short,
      // each item once.
      std::vector<std::atomic<int>> ranged(n);
      std::atomic<std::size_t> chunks{0};
      for_each_range(n, 100, true, [&](std::size_t c, std::size_t begin, std::size_t end) {
        chunks.fetch_add(1);
        EXPECT_EQ(begin, 100 * c);
        EXPECT_EQ(end, std::min(n, begin + 100));
        for (std::size_t i = begin; i < end; ++i) ranged[i].fetch_add(1);
      });
      EXPECT_EQ(chunks.load(), (n + 99) / 100) << n << " items";
      for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(ranged[i].load(), 1) << i;
      std::vector<std::atomic<int>> indexed(n);
      for_each_index(n, [&](std::size_t i) { indexed[i].fetch_add(1); });
      for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(indexed[i].load(), 1) << i;
    }
  }
  omp_set_num_threads(omp_get_num_procs());
}

// The body -> contact lists, built by shares of the contacts in parallel,
// are each body's contacts in contact order whatever the thread count;
// bodies not listed (infinite mass) get none.
TEST(Engine, ContactAdjacencyIsEachBodysContactsInOrderOnAnyThreads) {
  const std::size_t bodies = 1000, contacts = 20000;
  std::vector<std::int32_t> a(contacts), b(contacts);
  std::uint64_t state = 12345;
  auto next = [&] { return state = state * 6364136223846793005ULL + 1442695040888963407ULL; };
  for (std::size_t k = 0; k < contacts; ++k) {
    a[k] = std::int32_t(next() >> 33) % std::int32_t(bodies);
    b[k] = std::int32_t(next() >> 33) % std::int32_t(bodies);
  }
  auto listed = [](std::int32_t i) { return i % 10 != 0; };
  std::vector<std::vector<std::uint32_t>> expected(bodies);
  for (std::size_t k = 0; k < contacts; ++k) {
    if (listed(a[k])) expected[std::size_t(a[k])].push_back(std::uint32_t(k << 1));
    if (listed(b[k])) expected[std::size_t(b[k])].push_back(std::uint32_t(k << 1 | 1));
  }
  for (const int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    ContactAdjacency adj;
    for (int round = 0; round < 2; ++round) {  // again on the kept scratch
      adj.build(a, b, bodies, listed);
      ASSERT_EQ(adj.offset.size(), bodies + 1);
      for (std::size_t i = 0; i < bodies; ++i) {
        const std::vector<std::uint32_t> got(adj.entry.begin() + adj.offset[i],
                                             adj.entry.begin() + adj.offset[i + 1]);
        ASSERT_EQ(got, expected[i]) << "body " << i << ", " << threads << " threads";
      }
    }
  }
  omp_set_num_threads(omp_get_num_procs());
}

// ---------------------------------------------------------------- spatial order

// Reordering moves every per-particle array together, and the periodic
// Morton sort leaves neighbours adjacent: after it, particles on a line
// spawned in shuffled order come out in order along the line.
TEST(Engine, SpatialReorderMovesWholeParticles) {
  auto m = base_model();
  m->gravity = Vec3::Zero();
  m->reorder_interval = 1;
  m->reorder_min_particles = 0;
  World w(m);
  const int n = 50;
  for (int k = 0; k < n; ++k) {
    const int slot = (k * 17) % n;  // a shuffle of 0..n-1
    w.add_particle(0, 0.001, 0, Vec3(0.01 * slot, 0, 0), Quat::Identity(), Vec3(0, 0, 1e-3 * slot));
  }
  w.step();
  const Particles& p = w.particles();
  for (int j = 0; j < n; ++j) {
    const auto u = std::size_t(j);
    const int slot = int(std::lround(p.position[u].x() / 0.01));
    EXPECT_EQ(slot, j) << "not in order along the line";
    EXPECT_EQ(p.id[u], std::uint64_t((slot * 3) % n)) << "id did not move with its particle";  // 17 * 3 = 1 mod 50
    EXPECT_DOUBLE_EQ(p.velocity[u].z(), 1e-3 * slot);
    EXPECT_DOUBLE_EQ(p.mass[u], p.mass[0]);
  }
}

// The warm start finds last step's impulses by contact key after the
// spatial reorder has made particle-index order (the contacts' order)
// unlike key (id) order: a 4-layer stack added in shuffled order and
// reordered every step needs, once settled, under half the iterations per
// step that the same stack solved cold needs (with the lookup broken, the
// warm start needs as many as the cold).
TEST(Engine, WarmStartCarriesImpulsesAcrossSpatialReorder) {
  auto iterations = [](bool warm, bool& keys_unsorted) {
    auto m = base_model();
    m->bodies.push_back(test::ground_plane());
    m->solver.tolerance = 1e-6;
    m->solver.warm_start = warm;
    m->reorder_interval = 1;
    m->reorder_min_particles = 0;
    World w(m);
    const double r = 0.005;
    const int n = 36;
    for (int k = 0; k < n; ++k) {
      const int slot = (k * 17) % n, layer = slot / 9, i = slot % 3, j = slot / 3 % 3;
      w.add_particle(0, r, 0, Vec3(2 * r * i, r + 2 * r * layer, 2 * r * j));
    }
    int total = 0;
    for (int step = 0; step < 40; ++step) {
      const StepStats& s = w.step();
      if (step >= 20) total += s.solver.iterations;
    }
    const std::vector<ContactKey>& keys = w.contacts().key;
    keys_unsorted = !std::is_sorted(keys.begin(), keys.end());
    return total;
  };
  bool warm_unsorted = false, cold_unsorted = false;
  const int warm = iterations(true, warm_unsorted), cold = iterations(false, cold_unsorted);
  EXPECT_TRUE(warm_unsorted) << "the keys came in key order: the test misses its case";
  EXPECT_LT(2 * warm, cold) << "warm " << warm << ", cold " << cold << " iterations in 20 steps";
}

}  // namespace
}  // namespace ces
