// Scenes written to hurt: include chains and fan-outs, --set paths, files
// and documents past the bounds of scene/limits.hpp, includes that leave the
// scene's folder, messages that would quote files. Each must end in a clean
// SceneError naming the place, never a crash, a hang or a large allocation.
// (Single-file cases are in tests/bad_scenes/, checked by scene_test.cpp.)
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "scene/diagnostics.hpp"
#include "scene/limits.hpp"
#include "scene/scene.hpp"
#include "scene/schema.hpp"
#include "support.hpp"

namespace ces::scene {
namespace {

namespace fs = std::filesystem;

constexpr const char* kMinimal = "ces_sim: 1\ntime: {step: 1 ms, end: 0.1 s}\n";

fs::path write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

std::vector<Diagnostic> load_errors(const fs::path& path, const LoadOptions& options = {}) {
  try {
    load(path.string(), options);
  } catch (const SceneError& e) {
    return e.diagnostics();
  }
  ADD_FAILURE() << path << " loaded without errors";
  return {};
}

std::vector<Diagnostic> text_errors(const std::string& text, const std::string& name,
                                    const LoadOptions& options = {}) {
  try {
    load_text(text, (test::fresh_dir("hostile_text") / name).string(), options);
  } catch (const SceneError& e) {
    return e.diagnostics();
  }
  ADD_FAILURE() << name << " loaded without errors";
  return {};
}

std::string all(const std::vector<Diagnostic>& list) {
  std::string s;
  for (const Diagnostic& d : list) s += d.str() + "\n";
  return s;
}

// Exactly one diagnostic, containing `message`.
void expect_one(const std::vector<Diagnostic>& errors, const std::string& message) {
  ASSERT_EQ(errors.size(), 1u) << all(errors);
  EXPECT_NE(errors[0].str().find(message), std::string::npos) << all(errors);
  EXPECT_GT(errors[0].line, 0) << all(errors);
}

// ------------------------------------------------------------------ includes

// "f12.yaml" (built by appending: GCC 12 warns wrongly on "f" + std::string).
std::string numbered(int i) {
  std::string name = "f";
  name += std::to_string(i);
  name += ".yaml";
  return name;
}

// 3000 files, each including the next: the chain stops at the bound, at
// the include line of the file that would go past it.
TEST(HostileIncludes, LongChainIsRefusedAtTheBound) {
  const fs::path dir = test::fresh_dir("include_chain");
  for (int i = 1; i < 3000; ++i) write(dir / numbered(i), "include: " + numbered(i + 1) + "\n");
  const auto errors =
      load_errors(write(dir / "f0.yaml", std::string(kMinimal) + "include: f1.yaml\n"));
  expect_one(errors, "include: an include chain of more than 16 files");
  EXPECT_EQ(errors[0].file, (dir / "f15.yaml").string());
}

// Each file includes the next one twice: 2^12 reads without a bound on
// the files of one load.
TEST(HostileIncludes, FanOutIsBounded) {
  const fs::path dir = test::fresh_dir("include_fan");
  for (int i = 1; i < 12; ++i)
    write(dir / numbered(i), "include: [" + numbered(i + 1) + ", " + numbered(i + 1) + "]\n");
  write(dir / numbered(12), "seed: 1\n");
  const auto errors =
      load_errors(write(dir / "f0.yaml", std::string(kMinimal) + "include: f1.yaml\n"));
  expect_one(errors, "include: more than 64 included files in one scene");
}

// Symlinks are followed before the check: a link in the scene's folder to a
// file outside it is refused; a link inside, and a folder named by
// include_paths (--include-path), are not.
TEST(HostileIncludes, SymlinksAreResolvedBeforeTheCheck) {
  const fs::path dir = test::fresh_dir("include_links");
  write(dir / "outside" / "secret.yaml", "seed: 7\n");
  write(dir / "scene" / "parts" / "seed.yaml", "seed: 5\n");
  fs::create_symlink(dir / "outside" / "secret.yaml", dir / "scene" / "link_out.yaml");
  fs::create_directories(dir / "scene" / "sub");
  fs::create_symlink(dir / "outside", dir / "scene" / "sub" / "out");
  fs::create_symlink(dir / "scene" / "parts" / "seed.yaml", dir / "scene" / "link_in.yaml");

  const std::string base = std::string(kMinimal) + "include: ";
  expect_one(load_errors(write(dir / "scene" / "a.yaml", base + "link_out.yaml\n")),
             "include: 'link_out.yaml' is outside the folder of a.yaml");
  expect_one(load_errors(write(dir / "scene" / "b.yaml", base + "sub/out/secret.yaml\n")),
             "include: 'sub/out/secret.yaml' is outside the folder of b.yaml");
  EXPECT_EQ(load(write(dir / "scene" / "c.yaml", base + "link_in.yaml\n").string()).seed, 5u);

  LoadOptions options;
  options.include_paths = {(dir / "outside").string()};
  EXPECT_EQ(load((dir / "scene" / "a.yaml").string(), options).seed, 7u);
  EXPECT_EQ(
      load(write(dir / "scene" / "d.yaml", base + "../outside/secret.yaml\n").string(), options)
          .seed,
      7u);
}

// Fragments included by a fragment are held to the top scene's folder too,
// and a refusal reads nothing: it does not say whether the file exists.
TEST(HostileIncludes, NestedIncludesAndMissingFilesOutsideAreRefusedAlike) {
  const fs::path dir = test::fresh_dir("include_nested");
  write(dir / "scene" / "parts" / "a.yaml", "include: ../../elsewhere/b.yaml\n");
  write(dir / "elsewhere" / "b.yaml", "seed: 3\n");
  const auto nested = load_errors(
      write(dir / "scene" / "main.yaml", std::string(kMinimal) + "include: parts/a.yaml\n"));
  expect_one(nested, "include: '../../elsewhere/b.yaml' is outside the folder of");
  EXPECT_EQ(nested[0].file, (dir / "scene" / "parts" / "a.yaml").string());
  const auto missing = load_errors(
      write(dir / "scene" / "m.yaml", std::string(kMinimal) + "include: ../elsewhere/none.yaml\n"));
  expect_one(missing, "include: '../elsewhere/none.yaml' is outside the folder of");
}

// A file in the scene's tree that is not a scene: the message quotes at
// most the start of its first line, and every diagnostic is one line.
TEST(HostileIncludes, MessagesQuoteNoMoreThanTheOffendingLine) {
  const fs::path dir = test::fresh_dir("include_quote");
  write(dir / "notes.txt",
        "root:x:0:0:root:/root:/bin/bash\ndaemon:x:1:1:daemon:/usr/sbin:/usr/sbin/nologin\n"
        "bin:x:2:2:bin:/bin:/usr/sbin/nologin\n");
  const auto errors =
      load_errors(write(dir / "main.yaml", std::string(kMinimal) + "include: notes.txt\n"));
  ASSERT_EQ(errors.size(), 1u) << all(errors);
  const std::string shown = errors[0].str();
  EXPECT_NE(shown.find("got 'root:x:0:0:root:/root:/bin/bash..."), std::string::npos) << shown;
  EXPECT_EQ(shown.find("daemon"), std::string::npos) << shown;
  EXPECT_EQ(shown.find('\n'), std::string::npos) << shown;

  const auto escaped = text_errors(
      std::string(kMinimal) + "name: \"line one\\nline two\"\nseed: \"x\\ny\"\n", "escaped.yaml");
  for (const Diagnostic& d : escaped) EXPECT_EQ(d.str().find('\n'), std::string::npos) << d.str();
  EXPECT_NE(all(escaped).find("got 'x...'"), std::string::npos) << all(escaped);
}

TEST(HostileIncludes, LargeFilesAreRefusedBeforeReading) {
  const fs::path dir = test::fresh_dir("include_large");
  write(dir / "big.yaml", std::string(limits::kFileBytes + 1, '#'));
  expect_one(load_errors(write(dir / "main.yaml", std::string(kMinimal) + "include: big.yaml\n")),
             "include: cannot read '" + (dir / "big.yaml").string() +
                 "': 1048577 bytes, "
                 "expected at most 1048576");
  expect_one(text_errors(std::string(limits::kFileBytes + 1, '#'), "big.yaml"),
             "the file has 1048577 bytes, expected at most 1048576");
}

// ------------------------------------------------------------------ --set

TEST(HostileOverrides, KeyPathsAreBounded) {
  const fs::path scene = write(test::fresh_dir("set_paths") / "s.yaml", kMinimal);
  LoadOptions long_path;
  std::string path = "a";
  for (int i = 0; i < 60000; ++i) path += ".a";
  long_path.overrides = {{path, "1"}};
  expect_one(load_errors(scene, long_path), "a key path longer than 256 characters");

  LoadOptions deep;
  path = "a";
  for (int i = 0; i < 40; ++i) path += ".a";
  deep.overrides = {{path, "1"}};
  expect_one(load_errors(scene, deep), "a key path of 41 segments, expected at most 32");

  // An index no integer holds is no item, not an exception.
  LoadOptions index;
  index.overrides = {{"bodies", "[{name: a, geometry: {box: {size: [1, 1, 1]}}, material: m}]"},
                     {"bodies.99999999999999999999999.name", "b"}};
  expect_one(load_errors(scene, index), "'bodies' has no item '99999999999999999999999'");
}

TEST(HostileOverrides, MessagesSayWhatAPathIs) {
  const fs::path scene = write(test::fresh_dir("set_messages") / "s.yaml",
                               std::string(kMinimal) +
                                   "materials: {steel: {}}\n"
                                   "bodies: [{name: a, geometry: {box: {size: [1, 1, 1]}}, "
                                   "material: steel}]\n");
  LoadOptions blank;
  blank.removals = {""};
  expect_one(load_errors(scene, blank),
             "--unset:1:1: invalid key path '', expected keys, indices or item names joined by "
             "dots");
  // An --unset comes first whatever the order on the command line.
  LoadOptions emptied;
  emptied.removals = {"bodies.a"};
  emptied.overrides = {{"bodies.a.material", "steel"}};
  expect_one(load_errors(scene, emptied),
             "'bodies' has no item 'a', the list is empty here (every --unset applies before the "
             "--set values)");
}

TEST(HostileOverrides, ValuesAreHeldToTheSameBounds) {
  const fs::path scene = write(test::fresh_dir("set_values") / "s.yaml", kMinimal);
  LoadOptions utf8;
  utf8.overrides = {{"name", "caf\xc3"}};
  expect_one(load_errors(scene, utf8), "--set:1:");
  EXPECT_NE(all(load_errors(scene, utf8)).find("invalid UTF-8"), std::string::npos);

  LoadOptions deep;
  deep.overrides = {{"seed", std::string(40, '[') + "1" + std::string(40, ']')}};
  expect_one(load_errors(scene, deep), "nested deeper than 32 levels");
}

// ------------------------------------------------------------------ documents

TEST(HostileDocuments, ValuesAndKeysAreCounted) {
  std::string list = std::string(kMinimal) + "x: [0";
  for (std::size_t i = 0; i < limits::kValues; ++i) list += ",0";
  expect_one(text_errors(list + "]\n", "values.yaml"),
             "the scene expands to more than 200000 values");

  std::string keys = std::string(kMinimal) + "materials:\n";
  for (std::size_t i = 0; i <= limits::kKeys; ++i) keys += "  m" + std::to_string(i) + ": {}\n";
  expect_one(text_errors(keys, "keys.yaml"), "a mapping of 10001 keys, expected at most 10000");

  // One large scalar used through an alias many times: its bytes count each time.
  std::string text = std::string(kMinimal) + "a: &a '" + std::string(200000, 'x') + "'\nb: [*a";
  for (int i = 0; i < 100; ++i) text += ", *a";
  expect_one(text_errors(text + "]\n", "bytes.yaml"), "or 16 MB of text");
}

// An alias of a bad feed repeated into a long list: the report keeps the
// first errors found and counts the others, one per fault of every copy.
TEST(HostileDocuments, ErrorsPastTheShownOnesAreCounted) {
  const auto feeds = [](int copies) {
    std::string text = std::string(kMinimal) +
                       "a: &a {rate: x, size: y, shape: z, region: r, velocity: v, start: s}\n"
                       "feeds: [*a";
    for (int i = 1; i < copies; ++i) text += ", *a";
    return text + "]\n";
  };
  const std::size_t one = text_errors(feeds(1), "one.yaml").size();
  const std::size_t per_copy = text_errors(feeds(2), "two.yaml").size() - one;
  ASSERT_GE(per_copy, 6u);
  ASSERT_LT(one + per_copy, Diagnostics::kShownErrors);

  const int copies = 2000;  // more values than validate() checks in one piece
  ASSERT_GT(copies * 7, int(kPieceValues));
  const auto errors = text_errors(feeds(copies), "bomb.yaml");
  ASSERT_EQ(errors.size(), Diagnostics::kShownErrors + 1);
  const std::size_t unshown = one + (copies - 1) * per_copy - Diagnostics::kShownErrors;
  EXPECT_EQ(errors.back().str(), errors.back().file + ": " + std::to_string(unshown) +
                                     " more errors, not shown (the first 100 found are above)");
  for (std::size_t i = 0; i + 1 < errors.size(); ++i) EXPECT_GT(errors[i].line, 0);

  // Aliases of aliases, near the bound on values: a mix with four faults
  // (size, material, fraction, bogus) 150 times in each of 150 feeds with
  // three (name, rate, region), under three unknown keys (m, mm, f).
  std::string nested = std::string(kMinimal) +
                       "m: &m {shape: z, size: y, material: 1, fraction: q, bogus: 1}\n"
                       "mm: &mm [*m";
  for (int i = 1; i < 150; ++i) nested += ", *m";
  nested += "]\nf: &f {name: 1, rate: x, mix: *mm, region: r}\nfeeds: [*f";
  for (int i = 1; i < 150; ++i) nested += ", *f";
  const auto many = text_errors(nested + "]\n", "nested.yaml");
  ASSERT_EQ(many.size(), Diagnostics::kShownErrors + 1);
  EXPECT_EQ(many.back().message,
            std::to_string(150 * 150 * 4 + 150 * 3 + 3 - Diagnostics::kShownErrors) +
                " more errors, not shown (the first 100 found are above)");
}

// Each error reported twice, as a node that two passes check: the report
// shows the first 100 different ones and counts the rest once each.
TEST(HostileDocuments, ErrorsReportedTwiceAreShownAndCountedOnce) {
  Diagnostics diags;
  const int distinct = int(Diagnostics::kShownErrors) + 50;
  for (int pass = 0; pass < 2; ++pass)
    for (int i = 0; i < distinct; ++i)
      diags.error(Mark{"twice.yaml", i + 1, 3}, "feeds[" + std::to_string(i) + "]", "bad rate");
  try {
    diags.raise();
  } catch (const SceneError& e) {
    const std::vector<Diagnostic>& shown = e.diagnostics();
    ASSERT_EQ(shown.size(), Diagnostics::kShownErrors + 1);
    for (std::size_t i = 0; i < Diagnostics::kShownErrors; ++i)
      EXPECT_EQ(shown[i].line, int(i) + 1);
    EXPECT_EQ(shown.back().message, "50 more errors, not shown (the first 100 found are above)");
    return;
  }
  ADD_FAILURE() << "raise() did not throw";
}

TEST(HostileDocuments, DeepNestingIsAnErrorNotACrash) {
  for (const char* name : {"deep.yaml", "deep.json"}) {
    const std::string open(100000, '['), close(100000, ']');
    const auto errors = text_errors("{\"seed\": " + open + close + "}", name);
    ASSERT_FALSE(errors.empty());
    EXPECT_GT(errors[0].line, 0) << all(errors);
  }
  // Past yaml-cpp's own guard (about 500 levels), which says "bad file".
  std::string indented = kMinimal;
  for (int level = 0; level < 600; ++level) indented += std::string(2 * level, ' ') + "a:\n";
  expect_one(text_errors(indented, "indented.yaml"), "nested deeper than 32 levels");
  expect_one(text_errors("{\"ces_sim\": 1, \"seed\": " + std::string(40, '[') + "1" +
                             std::string(40, ']') + "}",
                         "deep40.json"),
             "nested deeper than 32 levels");
}

// yaml-cpp reads '<<' as an ordinary key: without a word of its own it
// would be "unknown key '<<'".
TEST(HostileDocuments, MergeKeysAreNamedAsUnsupported) {
  const auto errors = text_errors(std::string(kMinimal) +
                                      "solver: &s {max_iterations: 5}\n"
                                      "contact:\n  <<: *s\n",
                                  "merge.yaml");
  expect_one(errors,
             "merge.yaml:5:3: contact.<<: a YAML merge key ('<<'), which ces-sim does "
             "not support");
}

// Long plain scalars are scanned without recursion (a recursive
// std::regex overflows the stack on them); long digit strings are numbers
// out of range.
TEST(HostileDocuments, LongScalarsAreScannedWithoutRecursion) {
  expect_one(text_errors(std::string(kMinimal) + "seed: " + std::string(200000, '1') + "\n",
                         "digits.yaml"),
             "seed: 1111111111111111111111111111111111111111... is out of range");
  const auto words = text_errors(std::string(kMinimal) + "name: " + std::string(200000, 'a') +
                                     "\nseed: " + std::string(100000, 'b') + "\n",
                                 "words.yaml");
  expect_one(words, "seed: got 'bbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbb...', expected an integer");
}

// nlohmann's parser takes a NUL for the end of the text, so what follows
// would reach the YAML parser unchecked: control characters are refused
// first.
TEST(HostileDocuments, ControlCharactersAreRefusedWithTheirPlace) {
  const std::string nul("{\"ces_sim\": 1}\n\0garbage", 23);
  for (const char* name : {"nul.json", "nul.yaml"}) {
    const auto errors = text_errors(nul, name);
    expect_one(errors, std::string(name) + ":2:1: a control character (byte 0x00), expected "
                                           "printable text");
  }
  expect_one(text_errors(std::string(kMinimal) + "name: \"a\x1b[2Jb\"\n", "escape.yaml"),
             "escape.yaml:3:9: a control character (byte 0x1b)");
  // The same written as escapes, in a value and in a key, in YAML and JSON.
  expect_one(text_errors(std::string(kMinimal) + "name: \"a\\e[2Jb\"\n", "escaped.yaml"),
             "escaped.yaml:3:7: name: a control character (byte 0x1b, written as an escape)");
  expect_one(text_errors(std::string(kMinimal) + "\"na\\x00me\": x\n", "key.yaml"),
             "key.yaml:3:1: a control character (byte 0x00, written as an escape)");
  expect_one(text_errors("{\"ces_sim\": 1, \"time\": {\"step\": \"1 ms\", \"end\": \"1 s\"}, "
                         "\"name\": \"a\\u0007\"}",
                         "escaped.json"),
             "a control character (byte 0x07, written as an escape)");
}

TEST(HostileDocuments, JsonNumbersOutOfRangeHaveALine) {
  expect_one(text_errors("{\"ces_sim\": 1,\n \"time\": {\"step\": 1e999, \"end\": 1}}", "n.json"),
             "n.json:2:");
  EXPECT_NE(all(text_errors("{\"ces_sim\": 1,\n \"time\": {\"step\": 1e999}}", "n.json"))
                .find("number overflow"),
            std::string::npos);
  const auto tiny =
      text_errors("{\"ces_sim\": 1,\n \"time\": {\"step\": 1e-320, \"end\": 1}}", "s.json");
  expect_one(tiny, "time.step: 1e-320 is out of range");
  EXPECT_EQ(tiny[0].line, 2);
}

// ------------------------------------------------------------------ semantics

// A field grid is 0 outside its box: one that misses the drum's surface
// (here a 2 cm cube round the axis) loads, with a warning giving the share
// it covers and its box; one round the whole drum loads without.
TEST(HostileSemantics, AFieldGridMissingTheDrumWarns) {
  const fs::path dir = test::fresh_dir("grid_warning");
  auto grid = [&](const std::string& name, double half) {
    std::string text = "x,y,z,Ex,Ey,Ez\n";
    for (const double z : {-half, half})
      for (const double y : {-half, half})
        for (const double x : {-half, half})
          text +=
              std::to_string(x) + "," + std::to_string(y) + "," + std::to_string(z) + ",1e5,0,0\n";
    return write(dir / name, text).string();
  };
  const std::string scenes = std::string(CES_SOURCE_DIR) + "/scenes/";
  for (const auto& [file, expected] : {std::pair{grid("small.csv", 0.01), std::size_t(1)},
                                       std::pair{grid("whole.csv", 0.5), std::size_t(0)}}) {
    std::vector<Diagnostic> warnings;
    LoadOptions options;
    options.warnings = &warnings;
    options.removals = {"electrostatics.electrodes.wire"};
    options.overrides = {{"electrostatics.field", "{model: grid, file: " + file + "}"}};
    load(scenes + "ces_pcb.yaml", options);
    ASSERT_EQ(warnings.size(), expected) << file;
    if (expected) {
      EXPECT_NE(warnings[0].str().find("the field grid covers 0 % of the drum's surface (x -0.01 "
                                       "to 0.01, y -0.01 to 0.01, z -0.01 to 0.01 m)"),
                std::string::npos)
          << warnings[0].str();
    }
  }
}

// Warnings do not stop a load: feeds without gravity say so, and an
// explicit gravity of zero says it is meant.
TEST(HostileSemantics, FeedsWithoutGravityWarn) {
  const std::string feeds =
      "materials: {copper: {density: 8960 kg/m^3}}\n"
      "feeds:\n"
      "  - name: f\n"
      "    region: {box: {min: [0, 0, 0], max: [0.01, 0.01, 0.01]}}\n"
      "    rate: 10 /s\n"
      "    mix: [{material: copper, size: {constant: 1 mm}}]\n";
  const fs::path dir = test::fresh_dir("gravity_warning");
  std::vector<Diagnostic> warnings;
  LoadOptions options;
  options.warnings = &warnings;
  load(write(dir / "none.yaml", std::string(kMinimal) + feeds).string(), options);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_TRUE(warnings[0].warning);
  EXPECT_EQ(warnings[0].line, 4);
  EXPECT_NE(warnings[0].str().find(":4:1: warning: feeds: particles are fed but the scene gives "
                                   "no gravity"),
            std::string::npos)
      << warnings[0].str();
  warnings.clear();
  load(write(dir / "zero.yaml", std::string(kMinimal) + "gravity: [0, 0, 0]\n" + feeds).string(),
       options);
  load(
      write(dir / "down.yaml", std::string(kMinimal) + "gravity: [0, -9.81, 0]\n" + feeds).string(),
      options);
  EXPECT_TRUE(warnings.empty()) << all(warnings);
}

// Angles, angular speeds, voltages and fields need their unit, but zero is
// zero in any unit.
TEST(HostileSemantics, BareNumbersOnlyWhereUnambiguous) {
  const std::string body =
      "materials: {steel: {}}\n"
      "bodies:\n"
      "  - name: plate\n"
      "    geometry: {box: {size: [1, 1, 1]}}\n"
      "    material: steel\n"
      "    pose: {rotation: {axis: [0, 0, 1], angle: ANGLE}}\n";
  const auto with = [&](const std::string& angle) {
    std::string text = std::string(kMinimal) + body;
    text.replace(text.find("ANGLE"), 5, angle);
    return text;
  };
  EXPECT_NO_THROW(load_text(with("0"), "/tmp/zero.yaml"));
  EXPECT_NO_THROW(load_text(with("30 deg"), "/tmp/deg.yaml"));
  expect_one(text_errors(with("30"), "bare.yaml"),
             "bodies[0].pose.rotation.angle: a number without a unit is ambiguous here, "
             "expected an angle (rad)");
}

// Magnitudes no separator has, each refused at its line with its kind's
// bound (units::Kind::largest): they ran to plausible-looking products. A
// value at the bound loads.
TEST(HostileSemantics, MagnitudesBeyondAnySeparatorAreRefusedAtTheirLine) {
  const std::string scene = std::string(kMinimal) +
                            "materials: {steel: {}}\n"
                            "bodies:\n"
                            "  - name: drum\n"
                            "    geometry: {cylinder: {radius: 0.1 m, length: LENGTH}}\n"
                            "    material: steel\n"
                            "    motion: {rotation: {axis: [0, 0, 1], speed: SPEED}}\n"
                            "gravity: [0, GRAVITY, 0]\n";
  const auto with = [&](const std::string& length, const std::string& speed,
                        const std::string& gravity) {
    std::string text = scene;
    text.replace(text.find("LENGTH"), 6, length);
    text.replace(text.find("SPEED"), 5, speed);
    text.replace(text.find("GRAVITY"), 7, gravity);
    return text;
  };
  EXPECT_NO_THROW(load_text(with("100 km", "1e5 rad/s", "-1e4"), "/tmp/largest.yaml"));
  expect_one(text_errors(with("4e100", "1 rpm", "-9.81"), "long.yaml"),
             "long.yaml:6:50: bodies[0].geometry.cylinder.length: 4e100 is 4e+100 m, expected a "
             "length of at most 100000 m in magnitude");
  expect_one(text_errors(with("1 m", "1e12 rpm", "-9.81"), "fast.yaml"),
             "fast.yaml:8:49: bodies[0].motion.rotation.speed: '1e12 rpm' is 1.0472e+11 rad/s, "
             "expected an angular speed of at most 100000 rad/s in magnitude");
  expect_one(text_errors(with("1 m", "1 rpm", "-1e30"), "heavy.yaml"),
             "heavy.yaml:9:14: gravity[1]: -1e30 is -1e+30 m/s^2, expected an acceleration of at "
             "most 10000 m/s^2 in magnitude");
  expect_one(text_errors("ces_sim: 1\ntime: {step: 1 ms, end: 1e9 s}\n", "long_run.yaml"),
             "long_run.yaml:2:25: time.end: '1e9 s' is 1e+09 s, expected a time of at most");
}

// A particle lighter than the balance's unit or heavier than its bound
// is refused at the mix item, not at the step that draws one.
TEST(HostileSemantics, ParticleMassesOutsideTheBalanceAreRefusedAtTheirLine) {
  const std::string scene = std::string(kMinimal) +
                            "gravity: [0, -9.81, 0]\n"
                            "materials: {copper: {density: 8960 kg/m^3}}\n"
                            "feeds:\n"
                            "  - name: f\n"
                            "    region: {box: {min: [0, 0, 0], max: [0.1, 0.1, 0.1]}}\n"
                            "    rate: 10 /s\n"
                            "    mix:\n"
                            "      - {material: copper, SIZE}\n";
  const auto with = [&](const std::string& size) {
    std::string text = scene;
    text.replace(text.find("SIZE"), 4, size);
    return text;
  };
  // Reached ends: a uniform law's min, a drawn flake's thinnest and
  // narrowest; 1 nm of copper is 4.7e-24 kg.
  EXPECT_NO_THROW(load_text(with("size: {uniform: {min: 0.2 um, max: 1 mm}}"), "/tmp/fine.yaml"));
  expect_one(text_errors(with("size: {uniform: {min: 1 nm, max: 1 mm}}"), "dust.yaml"),
             "dust.yaml:10:9: feeds[0].mix[0]: feed 'f' makes particles of 4.69145e-24 kg, "
             "expected 1e-18 to 1e+09 kg");
  expect_one(text_errors(with("shape: flake, thickness: {uniform: {min: 1 nm, max: 0.2 mm}}, "
                              "width: {uniform: {min: 1 nm, max: 1 mm}}"),
                         "foil.yaml"),
             "foil.yaml:10:9: feeds[0].mix[0]: feed 'f' makes particles of");
  // A normal or lognormal law's far tail is not reached: a min of 0 there
  // makes no particle of 0 kg.
  EXPECT_NO_THROW(
      load_text(with("size: {normal: {mean: 1 mm, sd: 0.2 mm, min: 0 mm}}"), "/tmp/normal.yaml"));
  EXPECT_NO_THROW(
      load_text(with("size: {lognormal: {median: 1 mm, sigma: 0.5, min: 0 mm}}"), "/tmp/log.yaml"));
  // The heavy end: a 1 km boulder of copper (4.7e12 kg).
  const auto boulder = text_errors(with("size: {uniform: {min: 1 mm, max: 1 km}}"), "rock.yaml");
  EXPECT_NE(all(boulder).find("feed 'f' makes particles of 4.69145e+12 kg"), std::string::npos)
      << all(boulder);
}

// A region partly inside a body can still place particles: only a region
// wholly inside one is refused.
TEST(HostileSemantics, FeedRegionPartlyInsideABodyIsAccepted) {
  const std::string scene = std::string(kMinimal) +
                            "gravity: [0, -9.81, 0]\n"
                            "materials: {steel: {}, copper: {density: 8960 kg/m^3}}\n"
                            "bodies:\n"
                            "  - {name: block, geometry: {box: {size: [0.1, 0.1, 0.1]}}, "
                            "material: steel}\n"
                            "feeds:\n"
                            "  - name: f\n"
                            "    region: {box: {min: [0, 0, 0], max: [0.1, 0.1, 0.1]}}\n"
                            "    rate: 10 /s\n"
                            "    mix: [{material: copper, size: {constant: 1 mm}}]\n";
  EXPECT_NO_THROW(load_text(scene, "/tmp/partly.yaml"));
  std::string inside = scene;
  inside.replace(inside.find("max: [0.1, 0.1, 0.1]"), 20, "max: [0.04, 0.04, 0.04]");
  expect_one(text_errors(inside, "inside.yaml"), "the region lies inside body 'block'");
}

}  // namespace
}  // namespace ces::scene

namespace ces {
namespace {

// A checkpoint edited on purpose keeps a valid checksum (anyone can make
// one): what it holds is checked against the scene before a step reads it.
TEST(HostileCheckpoints, AStateUnlikeTheSceneIsRefused) {
  const Simulation sim = scene::load(std::string(CES_SOURCE_DIR) + "/scenes/default.yaml");
  const Model& model = *sim.model;
  const auto& materials = model.materials.materials();
  const int copper = int(std::find_if(materials.begin(), materials.end(),
                                      [](const Material& m) { return m.name == "copper"; }) -
                         materials.begin());
  ASSERT_LT(std::size_t(copper), materials.size());
  auto refused = [&](auto edit) -> std::string {
    State state;
    init_state(model, state);
    add_particle(model, state, 0, 1.0, copper, Vec3(0.0, 0.3, 0.0));
    edit(state.particles);
    try {
      check_loaded(model, state);
    } catch (const CorruptData& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(refused([](Particles&) {}), "");
  EXPECT_NE(refused([](Particles& p) { p.shape[0] = 1000000; }).find("its shape"),
            std::string::npos);
  EXPECT_NE(refused([](Particles& p) { p.shape[0] = -5; }).find("its shape"), std::string::npos);
  EXPECT_NE(refused([](Particles& p) { p.material[0] = 1000000; }).find("its material"),
            std::string::npos);
  EXPECT_NE(refused([](Particles& p) { p.carrier[0] = 99; }).find("carrying"), std::string::npos);
  EXPECT_NE(refused([](Particles& p) { p.position[0].x() = std::nan(""); }).find("its motion"),
            std::string::npos);
  EXPECT_NE(refused([](Particles& p) { p.orientation[0].coeffs().setZero(); }).find("its motion"),
            std::string::npos);
  EXPECT_NE(refused([](Particles& p) { p.mass[0] = -1.0; }).find("mass"), std::string::npos);
  EXPECT_NE(refused([](Particles& p) { p.scale[0] = 0.0; }).find("size"), std::string::npos);
}

}  // namespace
}  // namespace ces
