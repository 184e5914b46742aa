// STL/OBJ parts through assimp: one part per file. Assimp is not used for
// STEP: Debian's build sends AP203/AP214 to its IFC reader, which fails.
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cstdio>
#include <filesystem>

#include "parts.hpp"
#include "scene/text.hpp"

namespace ces::exporter {
namespace {

namespace fs = std::filesystem;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

bool is_mesh_file(const fs::path& p) {
  const std::string ext = lower(p.extension().string());
  return ext == ".stl" || ext == ".obj";
}

// Every mesh under `node`, moved by the node transforms down to it.
void collect(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent, Mesh& out) {
  const aiMatrix4x4 transform = parent * node.mTransformation;
  for (unsigned i = 0; i < node.mNumMeshes; ++i) {
    const aiMesh& m = *scene.mMeshes[node.mMeshes[i]];
    const auto base = std::uint32_t(out.vertices.size());
    for (unsigned v = 0; v < m.mNumVertices; ++v) {
      const aiVector3D p = transform * m.mVertices[v];
      out.vertices.emplace_back(p.x, p.y, p.z);
    }
    for (unsigned f = 0; f < m.mNumFaces; ++f)
      if (m.mFaces[f].mNumIndices == 3)  // points and lines carry no surface
        out.triangles.push_back({base + m.mFaces[f].mIndices[0], base + m.mFaces[f].mIndices[1],
                                 base + m.mFaces[f].mIndices[2]});
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c)
    collect(scene, *node.mChildren[c], transform, out);
}

Part read_one(const fs::path& file, double scale) {
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(file.string(), aiProcess_Triangulate);
  if (!scene || !scene->mRootNode)
    throw InputError("cannot read " + file.string() + ": " + importer.GetErrorString());
  Mesh raw;
  collect(*scene, *scene->mRootNode, aiMatrix4x4(), raw);
  if (raw.triangles.empty())
    throw InputError("cannot read " + file.string() + ": no triangles in it");
  Part part;
  part.name = file.stem().string();
  part.source = file.string();
  part.mesh.append(raw, scale);
  return part;
}

// A part's name is its file's stem, and goes into the scene and the JSON
// report, which hold UTF-8 text only.
void check_utf8_name(const fs::path& file) {
  const std::string name = file.filename().string();
  if (!scene::invalid_utf8(name)) return;
  std::string shown;
  for (const char ch : name) {
    const auto c = static_cast<unsigned char>(ch);
    char hex[5];
    std::snprintf(hex, sizeof hex, "\\x%02X", c);
    shown += c < 0x80 ? std::string(1, ch) : std::string(hex);
  }
  throw InputError("cannot read " + (file.parent_path() / shown).string() +
                   ": its name is not UTF-8 text, expected a UTF-8 file name (a part is named "
                   "after its file: rename it)");
}

std::vector<fs::path> mesh_files_in(const fs::path& folder) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(folder))
    if (e.is_regular_file() && is_mesh_file(e.path())) files.push_back(e.path());
  for (const fs::path& f : files) check_utf8_name(f);
  std::sort(files.begin(), files.end());  // directory order is not portable
  if (files.empty()) throw InputError("no .stl or .obj files in " + folder.string());
  return files;
}

}  // namespace

std::optional<double> unit_scale(const std::string& name) {
  const std::string n = lower(name);
  if (n == "mm" || n == "millimetre" || n == "millimeter") return 1e-3;
  if (n == "cm" || n == "centimetre" || n == "centimeter") return 1e-2;
  if (n == "m" || n == "metre" || n == "meter") return 1.0;
  if (n == "in" || n == "inch") return 0.0254;
  if (n == "ft" || n == "foot") return 0.3048;
  return std::nullopt;
}

std::vector<Part> read_mesh_files(const std::string& path, double scale) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError("cannot read " + path + ": no such file or folder");
  if (!fs::is_directory(path, ec)) {
    if (!is_mesh_file(path)) throw InputError("cannot read " + path + ": expected .stl or .obj");
    return {read_one(path, scale)};
  }
  std::vector<Part> parts;
  for (const fs::path& f : mesh_files_in(path)) parts.push_back(read_one(f, scale));
  return parts;
}

}  // namespace ces::exporter
