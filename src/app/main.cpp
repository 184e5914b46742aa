// Minimal ces-sim until the scene loader lands: drops spheres on a turning
// drum and prints per-step solver statistics.
#include <cstdio>
#include <memory>

#include "dynamics/world.hpp"

int main() {
  using namespace ces;
  auto m = std::make_shared<Model>();
  m->materials = MaterialTable({{"steel", 7800, 0.5, 0}, {"copper", 8960, 0.3, 0}}, {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  RigidBody drum;
  drum.name = "drum";
  drum.kind = BodyKind::Kinematic;
  drum.shape = geo::Cylinder{0.16, 0.15, 0.0};
  drum.motion.angular_speed = -44.8 * 2 * kPi / 60;
  m->bodies.push_back(drum);
  World w(m);
  for (int i = 0; i < 200; ++i)
    w.add_particle(0, 0.0005, 1, Vec3(-0.05 + 0.0011 * (i % 40), 0.17 + 0.0011 * (i / 40), 0.0));
  for (int s = 0; s < 500; ++s) {
    const StepStats& st = w.step();
    if (st.step % 100 == 0)
      std::printf("t=%.3f s contacts=%zu iterations=%d residual=%.2e\n", st.time, st.contacts,
                  st.solver.iterations, st.solver.residual);
  }
  return 0;
}
