// The bounds a scene must keep, each refused with a diagnostic at the line
// that breaks it. They hold hostile input (alias bombs, include chains,
// deep nesting, runs that would never end) to bounded time and memory,
// as parsers for untrusted text do, and sit far above any real scene.
#pragma once
#include <cstddef>
#include <cstdint>

namespace ces::scene::limits {

// Bytes in one scene file or fragment.
inline constexpr std::size_t kFileBytes = 1u << 20;
// Fragments in one include chain, and files read in one load.
inline constexpr int kIncludeDepth = 16;
inline constexpr int kIncludeFiles = 64;
// Levels of nested mappings and lists; segments of a --set key path.
inline constexpr int kNesting = 32;
// Values in one load, and bytes of their text (scalars, keys), counted
// with YAML aliases expanded: each use of an alias counts its value again.
inline constexpr std::size_t kValues = 200000;
inline constexpr std::size_t kTextBytes = 16u << 20;
// Keys in one mapping; characters in a key path (feeds[0].mix[1].size).
inline constexpr std::size_t kKeys = 10000;
inline constexpr std::size_t kPathBytes = 256;
// Bytes of a mesh or field grid file; a sphere-list file is held to
// kFileBytes.
inline constexpr std::uintmax_t kDataFileBytes = 256u << 20;
// Particle shapes a scene builds (each shapes entry fed, each built-in
// flake or rod aspect), and spheres in one shape: building one integrates
// its volume, up to about a second.
inline constexpr std::size_t kParticleShapes = 16;
inline constexpr std::size_t kShapeSpheres = 1000;
// A shape's extent over its smallest sphere's radius: a cluster wider than
// this is no particle, and its volume integral (down to a 64th of the
// smallest radius) loses the small spheres or overflows.
inline constexpr double kShapeSpan = 1e4;
// A shape's `size` over its spheres' bounding diameter, or under: further
// off, its spheres are specks or giants of the size the feed draws, and
// its particles weigh nothing or more than the balance counts.
inline constexpr double kShapeScale = 1e4;
// Materials (their pair table has one entry per ordered pair), and bin
// tallies: bins of all collectors times materials, 32 bytes each.
inline constexpr std::size_t kMaterials = 256;
inline constexpr double kBinTallies = 1e7;
// Time steps in a run (time.end / time.step), and trajectory frames.
inline constexpr double kSteps = 1e7;
inline constexpr double kFrames = 1e5;
// Particles a run's feeds make, all feeds together (expected number).
inline constexpr double kFedParticles = 1e7;

}  // namespace ces::scene::limits
