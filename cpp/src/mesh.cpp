#include "nbv/mesh.hpp"
#include "nbv/obj.hpp"
#include "nbv/ply.hpp"
#include "nbv/stl.hpp"

#include <assimp/DefaultIOStream.h>
#include <assimp/DefaultIOSystem.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/DefaultLogger.hpp>
#include <assimp/Importer.hpp>
#include <assimp/LogStream.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace nbv {

namespace {
// Why a valid mesh has no surface to see, sample or score ("" if it has one): all its triangles
// degenerate, or an area too large for double.
std::string area_problem(const Mesh& m) {
  const double area = m.area();
  if (area > 0 && std::isfinite(area)) return "";
  // (finite vertices: a NaN area is an overflow, inf - inf in a cross product)
  const bool overflow = area > 0 || std::isnan(area);
  return "its " + std::to_string(m.faces.rows()) + " triangles have " +
         (overflow ? "an infinite area (coordinates too large)" : "no area (all degenerate)");
}
}  // namespace

Mesh Mesh::from_arrays(const PointsRef& vertices, const Eigen::Ref<const Faces>& faces) {
  Mesh m;
  m.vertices = vertices;
  m.faces = faces;
  m.validate();
  if (const std::string why = area_problem(m); !why.empty())
    throw std::invalid_argument("mesh: " + why);
  return m;
}

void Mesh::validate() const {
  if (vertices.rows() == 0) throw std::invalid_argument("mesh has no vertices");
  if (faces.rows() == 0) throw std::invalid_argument("mesh has no triangles");
  require_finite(vertices, "mesh vertices");
  const auto n = static_cast<std::int64_t>(vertices.rows());
  const std::int64_t lo = faces.minCoeff(), hi = faces.maxCoeff();
  if (lo < 0 || hi >= n)
    throw std::invalid_argument("mesh face indices out of range: found [" + std::to_string(lo) +
                                ", " + std::to_string(hi) + "] for " + std::to_string(n) +
                                " vertices");
}

Eigen::VectorXd Mesh::triangle_areas() const {
  Eigen::VectorXd a(faces.rows());
  for (Eigen::Index i = 0; i < faces.rows(); ++i) {
    const Eigen::Vector3d p0 = vertices.row(faces(i, 0)), p1 = vertices.row(faces(i, 1)),
                          p2 = vertices.row(faces(i, 2));
    a[i] = 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

double Mesh::area() const { return triangle_areas().sum(); }

Eigen::AlignedBox3d Mesh::bounds() const {
  Eigen::AlignedBox3d box;
  for (Eigen::Index i = 0; i < faces.rows(); ++i)
    for (int k = 0; k < 3; ++k) box.extend(Eigen::Vector3d(vertices.row(faces(i, k))));
  return box;
}

Points Mesh::sample_surface(std::size_t n, std::uint64_t seed, Eigen::VectorXi* face_ids) const {
  const Eigen::VectorXd areas = triangle_areas();
  std::vector<double> cdf(static_cast<std::size_t>(areas.size()));
  double acc = 0;
  for (Eigen::Index i = 0; i < areas.size(); ++i) cdf[i] = (acc += areas[i]);
  if (!(acc > 0)) throw std::invalid_argument("cannot sample a mesh of zero surface area");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Points out(static_cast<Eigen::Index>(n), 3);
  if (face_ids) face_ids->resize(static_cast<Eigen::Index>(n));
  for (std::size_t s = 0; s < n; ++s) {
    const double r = U(rng) * acc;
    auto it = std::upper_bound(cdf.begin(), cdf.end(), r);
    const auto f = static_cast<Eigen::Index>(
        std::min<std::ptrdiff_t>(it - cdf.begin(), static_cast<std::ptrdiff_t>(cdf.size()) - 1));
    const double u = U(rng), v = U(rng), su = std::sqrt(u);
    const double b0 = 1 - su, b1 = su * (1 - v), b2 = su * v;
    out.row(static_cast<Eigen::Index>(s)) = b0 * vertices.row(faces(f, 0)) +
                                            b1 * vertices.row(faces(f, 1)) +
                                            b2 * vertices.row(faces(f, 2));
    if (face_ids) (*face_ids)[static_cast<Eigen::Index>(s)] = static_cast<int>(f);
  }
  return out;
}

namespace {

// The file system assimp sees: every file it asks about or opens (the mesh file, and any file
// the mesh file names) must be a regular file of at most kMaxMeshFileBytes. Any other is reported
// missing to assimp and remembered, and load_mesh refuses the mesh naming it: assimp's own
// DefaultIOSystem opened a FIFO named by an OBJ's `mtllib` or a glTF's buffer and blocked forever
// (with SIGINT ignored). Files are opened with O_NONBLOCK and checked with fstat on the open
// descriptor, so a path swapped for a FIFO between the check and the open cannot block either.
class RegularFileIOSystem : public Assimp::DefaultIOSystem {
 public:
  bool Exists(const char* file) const override {
    struct stat st;
    if (::stat(file, &st) != 0) return false;
    return accept(file, st);
  }

  Assimp::IOStream* Open(const char* file, const char* mode = "rb") override {
    if (std::string(mode).find_first_of("wa+") != std::string::npos) return nullptr;
    const int fd = ::open(file, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return nullptr;
    struct stat st;
    if (::fstat(fd, &st) != 0 || !accept(file, st)) {
      ::close(fd);
      return nullptr;
    }
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
    FILE* f = ::fdopen(fd, "rb");
    if (!f) {
      ::close(fd);
      return nullptr;
    }
    return new Stream(f, file);
  }

  /// The first file refused and why ("" if none).
  const std::string& refused() const { return refused_; }
  const std::string& refused_why() const { return refused_why_; }

 private:
  struct Stream : Assimp::DefaultIOStream {
    Stream(FILE* f, const std::string& name) : Assimp::DefaultIOStream(f, name) {}
  };

  bool accept(const char* file, const struct stat& st) const {
    const std::string why =
        why_not_readable(st.st_mode, static_cast<std::uintmax_t>(st.st_size), kMaxMeshFileBytes);
    if (why.empty()) return true;
    if (refused_.empty()) refused_ = file, refused_why_ = why;
    return false;
  }

  mutable std::string refused_, refused_why_;
};

// The vertices that faces use and that have a NaN or infinite coordinate, over the parts of a
// file; refuse() throws naming the file, how many and the first. Checked on the vertices as read:
// assimp's JoinIdenticalVertices would merge such a vertex into another, and a scale could hide
// or make one.
class NonFiniteVertices {
 public:
  // The vertices of one part that `used` marks; at(v) is vertex v (an Eigen::Vector3d). The
  // message names the first as the file does: vertex number[v] (v where `number` is empty) and
  // `part` (" of part 2", or "").
  template <class At>
  void add(const std::vector<char>& used, const At& at, const std::string& part = "",
           const std::vector<std::int64_t>& number = {}) {
    for (std::size_t v = 0; v < used.size(); ++v) {
      if (!used[v]) continue;
      const Eigen::Vector3d p = at(v);
      if (p.allFinite()) continue;
      if (count_++ == 0)
        first_ = "vertex " + std::to_string(number.empty() ? std::int64_t(v) : number[v]) + part +
                 " is (" + fmt(p.x()) + ", " + fmt(p.y()) + ", " + fmt(p.z()) + ")";
    }
  }

  void refuse(const std::string& path) const {
    if (count_)
      throw std::invalid_argument("mesh file '" + path + "': " + std::to_string(count_) +
                                  " vertices of its faces have a NaN or infinite coordinate (" +
                                  first_ + ")");
  }

 private:
  std::size_t count_ = 0;
  std::string first_;
};

// A loaded mesh: Mesh::validate, and at least one triangle with an area (a mesh of degenerate
// triangles alone has no surface to see, sample or score; after a scale other than 1, the scale
// is named as the likely cause).
void validate_loaded(const Mesh& m, const std::string& path, double scale) {
  try {
    m.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("mesh file '" + path + "': " + e.what());
  }
  const std::string why = area_problem(m);
  if (why.empty()) return;
  std::ostringstream msg;
  msg << "mesh file '" << path << "': " << why;
  if (scale != 1.0) msg << " at mesh scale " << scale << ": is the scale right?";
  throw std::invalid_argument(msg.str());
}

// " (it looks like a PLY file: ...)" for a file whose first bytes are another mesh format's
// than its extension says (a PLY named .obj read as OBJ found no faces); "" otherwise.
std::string other_format(const std::string& path) {
  std::string head;
  try {
    head = read_file_head(path, 512, "mesh", kMaxMeshFileBytes);
  } catch (const std::exception&) {
    return "";
  }
  const auto starts = [&](const char* magic) { return head.rfind(magic, 0) == 0; };
  std::string name, ext;
  if (starts("ply\n") || starts("ply\r"))
    name = "PLY", ext = ".ply";
  else if (starts("glTF"))
    name = "binary glTF", ext = ".glb";
  else if (starts("{") && head.find("\"asset\"") != std::string::npos)
    name = "glTF", ext = ".gltf";
  else if (starts("<?xml") || head.find("<COLLADA") != std::string::npos)
    name = "Collada (XML)", ext = ".dae";
  else if (starts("solid ") || starts("solid\n") || starts("solid\r"))
    name = "ASCII STL", ext = ".stl";
  else if (starts("OFF\n") || starts("OFF\r") || starts("OFF "))
    name = "OFF", ext = ".off";
  std::string own = std::filesystem::path(path).extension().string();
  std::transform(own.begin(), own.end(), own.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (name.empty() || own == ext) return "";
  return " (it looks like a " + name + " file: name it " + ext +
         ", the extension nbvkit reads it by)";
}

// A mesh read in double precision by nbvkit's own readers (PLY, OBJ): at least one face, the
// vertices of faces finite, scaled, turned z up, validated. `number`: each vertex's number in the
// file, for the messages (empty: its row).
Mesh loaded_mesh(Points vertices, Faces faces, const std::string& path, double scale, char up,
                 const std::vector<std::int64_t>& number = {}) {
  if (faces.rows() == 0)
    throw std::invalid_argument("mesh file '" + path + "' contains no triangles" +
                                other_format(path));
  std::vector<char> used(static_cast<std::size_t>(vertices.rows()), 0);
  for (Eigen::Index i = 0; i < faces.size(); ++i)  // indices in range: the readers checked them
    used[static_cast<std::size_t>(faces.data()[i])] = 1;
  NonFiniteVertices bad;
  bad.add(
      used, [&](std::size_t v) { return Eigen::Vector3d(vertices.row(Eigen::Index(v))); }, "",
      number);
  bad.refuse(path);
  if (!vertices.allFinite()) {  // unused vertices with NaN (a PCL organized cloud's): dropped
    std::vector<std::int32_t> keep(used.size(), -1);
    Eigen::Index kept = 0;
    for (std::size_t v = 0; v < used.size(); ++v)
      if (used[v]) {
        keep[v] = static_cast<std::int32_t>(kept);
        vertices.row(kept++) = vertices.row(static_cast<Eigen::Index>(v));
      }
    vertices.conservativeResize(kept, 3);
    for (Eigen::Index i = 0; i < faces.size(); ++i)
      faces.data()[i] = keep[static_cast<std::size_t>(faces.data()[i])];
  }
  Mesh out;
  out.vertices.resize(vertices.rows(), 3);
  const bool y_up = (up == 'y' || up == 'Y');
  for (Eigen::Index i = 0; i < vertices.rows(); ++i) {
    const Eigen::Vector3d p = vertices.row(i).transpose();
    out.vertices.row(i) = scale * (y_up ? Eigen::Vector3d(p.x(), -p.z(), p.y()) : p);
  }
  out.faces = std::move(faces);
  validate_loaded(out, path, scale);
  return out;
}

// Refuses a file whose faces (of any polygon size) use a vertex with a NaN or infinite
// coordinate.
void check_finite_vertices(const aiScene& scene, const std::string& path) {
  NonFiniteVertices bad;
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) {
    const aiMesh* mesh = scene.mMeshes[m];
    std::vector<char> used(mesh->mNumVertices, 0);
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices < 3) continue;
      for (unsigned k = 0; k < face.mNumIndices; ++k)
        if (face.mIndices[k] < mesh->mNumVertices) used[face.mIndices[k]] = 1;
    }
    const auto at = [&](std::size_t v) {
      const aiVector3D& p = mesh->mVertices[v];
      return Eigen::Vector3d(p.x, p.y, p.z);
    };
    bad.add(used, at, " of part " + std::to_string(m));
  }
  bad.refuse(path);
}

// PLY files go through nbvkit's own strict reader (nbv/ply.hpp), never through assimp.
Mesh load_ply_mesh(const std::string& path, double scale, char up) {
  PlyData ply = read_ply(path, /*read_faces=*/true);
  return loaded_mesh(std::move(ply.vertices), std::move(ply.faces), path, scale, up);
}

// OBJ and OFF files go through nbvkit's own readers (nbv/obj.hpp) in double precision: assimp
// keeps float32, and a georeferenced file lost its digits before mesh.shift could be applied;
// assimp's OFF reader also clamps a face's out-of-range index to the last vertex.
Mesh load_obj_mesh(const std::string& path, double scale, char up, bool off) {
  ObjData obj = off ? read_off(path) : read_obj(path);
  return loaded_mesh(std::move(obj.vertices), std::move(obj.faces), path, scale, up,
                     obj.file_number);
}

// Files assimp reads arrive in float32 (Debian's assimp has ai_real = float), node transforms
// too. Refuses a mesh whose placed coordinates (`placed`, in file units) are large enough that
// float32 rounds them by more than kMaxFloat32RoundingMetres (after `scale`): half the float32
// spacing at the largest magnitude. At scale 1 that is every coordinate of magnitude 32768 m (2^15)
// or more (spacing 3.9 mm); up to there the rounding is at most 0.98 mm. The message says whether
// the file itself stores float32 (binary STL, glTF) or assimp dropped the file's digits (text
// formats).
void check_float32_precision(const Points& placed, const std::string& path, const std::string& ext,
                             double scale) {
  const float amax = placed.rows() ? static_cast<float>(placed.cwiseAbs().maxCoeff()) : 0.0f;
  if (!std::isfinite(amax)) return;  // validate_loaded refuses it
  const double spacing =
      static_cast<double>(std::nextafter(amax, std::numeric_limits<float>::infinity())) - amax;
  const double rounding = 0.5 * spacing * scale;
  if (rounding <= kMaxFloat32RoundingMetres) return;
  const bool binary_stl = ext == ".stl";  // only binary STL comes here as .stl
  const bool gltf = ext == ".gltf" || ext == ".glb";
  const std::string near =
      "with coordinates near the origin (subtract a local origin from every vertex and give it "
      "back with mesh.shift / --mesh-shift, which nbvkit adds in double precision)";
  const std::string dbl = "as PLY or OBJ, which nbvkit reads in double precision";
  std::string why;
  if (binary_stl)
    why =
        "binary STL stores float32 coordinates, so the file itself has already lost this "
        "precision: export the mesh again from its source, " +
        near + " or " + dbl;
  else if (gltf)
    why =
        "glTF stores positions in float32 and assimp applies node transforms in float32: "
        "export the mesh again from its source, " +
        near + " or " + dbl;
  else
    why = "assimp, which reads '" + printable_ascii(ext) +
          "' files for nbvkit, keeps coordinates in float32 (the file's own digits are finer): "
          "save the mesh " +
          near + " or " + dbl;
  char reach[64];
  std::snprintf(reach, sizeof reach, "%.1f", static_cast<double>(amax));
  throw std::invalid_argument(
      "cannot read mesh '" + path + "': its coordinates reach " + reach +
      " (file units; mesh scale " + fmt(scale) + "), where float32 numbers are " +
      fmt(spacing * scale) + " m apart: vertices would be off by up to " + fmt(rounding) +
      " m, more than the " + fmt(kMaxFloat32RoundingMetres) + " m nbvkit accepts; " + why);
}

// STL files go through nbvkit's own reader (nbv/stl.hpp): ASCII STL in double precision, any
// case and line end, facets of more than three vertices cut (assimp kept three of four). A
// binary STL stores float32, so its coordinates are checked as assimp's are.
Mesh load_stl_mesh(const std::string& path, double scale, char up) {
  StlData stl = read_stl(path);
  if (stl.binary) check_float32_precision(stl.vertices, path, ".stl", scale);
  return loaded_mesh(std::move(stl.vertices), std::move(stl.faces), path, scale, up);
}

// Triangles the node tree may place when it places more than the file stores (a mesh referenced
// by many nodes): a 380 KB glTF placing one mesh 10,000 times held 4.5 GB.
constexpr std::int64_t kMaxInstancedTriangles = 20'000'000;

// The triangles of every mesh instance in the node tree, placed by the node's accumulated
// transform (in double precision) and in file units: `vertices` (N, 3), `faces` (M, 3). A
// transform that mirrors (negative determinant) turns the winding: its triangles are written
// reversed, so a mirrored part is not inside-out (assimp's PreTransformVertices keeps the
// winding). Deep node trees are walked without recursion. Refused: a face index outside its
// part, a scene placing more vertices than int32 indices address, or more than
// kMaxInstancedTriangles triangles by instancing.
void place_instances(const aiScene& scene, const std::string& path, Points& vertices,
                     Faces& faces) {
  using Matrix = Eigen::Matrix4d;
  const auto matrix = [](const aiMatrix4x4& a) {
    Matrix m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = a[r][c];
    return m;
  };
  struct Instance {
    const aiMesh* mesh;
    Matrix m;
  };
  std::vector<Instance> instances;
  std::int64_t nv = 0, nf = 0, stored = 0;  // placed vertices and triangles; triangles stored
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) stored += scene.mMeshes[m]->mNumFaces;
  std::vector<std::pair<const aiNode*, Matrix>> stack;
  if (scene.mRootNode)
    stack.emplace_back(scene.mRootNode, matrix(scene.mRootNode->mTransformation));
  while (!stack.empty()) {
    const auto [node, m] = stack.back();
    stack.pop_back();
    for (unsigned i = 0; i < node->mNumMeshes; ++i) {
      if (node->mMeshes[i] >= scene.mNumMeshes) continue;
      const aiMesh* mesh = scene.mMeshes[node->mMeshes[i]];
      if (!(mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
      instances.push_back({mesh, m});
      nv += mesh->mNumVertices;
      for (unsigned f = 0; f < mesh->mNumFaces; ++f) nf += mesh->mFaces[f].mNumIndices == 3;
      if (nv > std::numeric_limits<std::int32_t>::max() ||
          (nf > kMaxInstancedTriangles && nf > stored))
        throw std::invalid_argument(
            "cannot read mesh '" + path + "': its nodes place " + std::to_string(instances.size()) +
            " copies of its meshes, more than " + std::to_string(kMaxInstancedTriangles) +
            " triangles (or 2^31 vertices) in all; nbvkit takes up to that many from instancing");
    }
    for (unsigned c = node->mNumChildren; c-- > 0;)  // children in file order
      stack.emplace_back(node->mChildren[c], m * matrix(node->mChildren[c]->mTransformation));
  }
  vertices.resize(nv, 3);
  faces.resize(nf, 3);
  Eigen::Index vbase = 0, fi = 0;
  for (const Instance& in : instances) {
    const Eigen::Matrix3d linear = in.m.topLeftCorner<3, 3>();
    const Eigen::Vector3d shift = in.m.topRightCorner<3, 1>();
    const bool mirrored = linear.determinant() < 0;
    for (unsigned v = 0; v < in.mesh->mNumVertices; ++v) {
      const aiVector3D& p = in.mesh->mVertices[v];
      vertices.row(vbase + v) = (linear * Eigen::Vector3d(p.x, p.y, p.z) + shift).transpose();
    }
    for (unsigned f = 0; f < in.mesh->mNumFaces; ++f) {
      const aiFace& face = in.mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;
      for (int k = 0; k < 3; ++k)
        if (face.mIndices[k] >= in.mesh->mNumVertices)
          throw std::invalid_argument("cannot read mesh '" + path + "': a face uses vertex " +
                                      std::to_string(face.mIndices[k]) + " of a part of " +
                                      std::to_string(in.mesh->mNumVertices));
      for (int k = 0; k < 3; ++k)
        faces(fi, mirrored && k ? 3 - k : k) = static_cast<std::int32_t>(vbase + face.mIndices[k]);
      ++fi;
    }
    vbase += in.mesh->mNumVertices;
  }
}

bool all_digits(const std::string& v) {
  return !v.empty() && v.size() <= 9 && v.find_first_not_of("0123456789") == std::string::npos;
}

// The value of attribute `name` in a start tag's text, or nullopt.
std::optional<std::string> attribute(const std::string& tag, const std::string& name) {
  for (std::size_t i = tag.find(name); i != std::string::npos; i = tag.find(name, i + 1)) {
    if (i == 0 || !std::isspace(static_cast<unsigned char>(tag[i - 1]))) continue;
    std::size_t j = i + name.size();
    while (j < tag.size() && std::isspace(static_cast<unsigned char>(tag[j]))) ++j;
    if (j >= tag.size() || tag[j] != '=') continue;
    ++j;
    while (j < tag.size() && std::isspace(static_cast<unsigned char>(tag[j]))) ++j;
    if (j >= tag.size() || (tag[j] != '"' && tag[j] != '\'')) return std::string();
    const std::size_t k = tag.find(tag[j], j + 1);
    if (k == std::string::npos) return std::string();
    return tag.substr(j + 1, k - j - 1);
  }
  return std::nullopt;
}

// Collada files: assimp 5.2's reader writes out of bounds for a <float_array> whose count is
// missing or wrong, and loops forever on a token that is not an unsigned integer in an index list
// (<p>, <vcount>, <v>, <h>). Such files are refused here, before assimp sees them; so are count,
// stride, offset and set attributes that are not unsigned integers.
void check_collada(const std::string& path) {
  const std::string s = read_whole_file(path, "mesh", kMaxMeshFileBytes);
  const auto fail = [&](const std::string& why) {
    throw std::invalid_argument("cannot read mesh '" + path + "': " + printable_ascii(why));
  };
  long long last_array = 0;  // values in the last <float_array> (or other array) read
  for (std::size_t pos = s.find('<'); pos != std::string::npos; pos = s.find('<', pos + 1)) {
    const std::size_t end = s.find('>', pos);
    if (end == std::string::npos) return;  // malformed XML: assimp's parser reports it
    const std::string tag = s.substr(pos + 1, end - pos - 1);
    std::size_t n = 0;
    while (n < tag.size() && !std::isspace(static_cast<unsigned char>(tag[n])) && tag[n] != '/')
      ++n;
    std::string name = tag.substr(0, n);
    if (const auto colon = name.rfind(':'); colon != std::string::npos)
      name = name.substr(colon + 1);
    if (name.empty() || name[0] == '/' || name[0] == '?' || name[0] == '!') continue;
    for (const char* a : {"count", "stride", "offset", "set"}) {
      const auto v = attribute(tag, a);
      if (v && !all_digits(*v))
        fail(std::string("<") + name + "> attribute " + a + "=\"" + v->substr(0, 40) +
             "\" is not an unsigned integer below 1e9");
      if (v && std::string(a) == "stride" && std::stoll(*v) == 0)
        fail("<" + name + "> has stride 0");
    }
    if (name == "accessor") {  // its values must lie within the array read before it
      const auto count = attribute(tag, "count"), stride = attribute(tag, "stride"),
                 offset = attribute(tag, "offset");
      const long long need = (count ? std::stoll(*count) : 0) * (stride ? std::stoll(*stride) : 1) +
                             (offset ? std::stoll(*offset) : 0);
      if (need > last_array)
        fail("<accessor> reads " + std::to_string(need) + " values of an array of " +
             std::to_string(last_array));
    }
    if (name != "float_array" && name.size() > 6 &&
        name.compare(name.size() - 6, 6, "_array") == 0) {
      const auto count = attribute(tag, "count");  // int_array, Name_array, ...
      last_array = count ? std::stoll(*count) : 0;
    }
    const bool self_closing = !tag.empty() && tag.back() == '/';
    const bool is_floats = name == "float_array";
    const bool is_indices = name == "p" || name == "vcount" || name == "v" || name == "h";
    if (!(is_floats || is_indices) || self_closing) continue;
    const std::size_t close = s.find("</", end);
    const std::string body = s.substr(end + 1, close == std::string::npos ? 0 : close - end - 1);
    if (is_indices) {
      if (body.find_first_not_of("0123456789 \t\r\n") != std::string::npos)
        fail("<" + name + "> holds something other than unsigned integers");
      continue;
    }
    const auto count = attribute(tag, "count");
    if (!count) fail("<float_array> without a count attribute");
    std::size_t tokens = 0;
    for (std::size_t i = 0; i < body.size();) {
      while (i < body.size() && std::isspace(static_cast<unsigned char>(body[i]))) ++i;
      if (i == body.size()) break;
      std::size_t j = i;
      while (j < body.size() && !std::isspace(static_cast<unsigned char>(body[j]))) ++j;
      const std::string tok = body.substr(i, j - i);
      char* e = nullptr;
      std::strtod(tok.c_str(), &e);
      if (e == tok.c_str() || *e != '\0') fail("<float_array> holds '" + tok.substr(0, 40) + "'");
      ++tokens;
      i = j;
    }
    if (std::to_string(tokens) != *count && !(tokens == 0 && std::stoll(*count) == 0))
      fail("<float_array> declares count=" + *count + " but holds " + std::to_string(tokens) +
           " numbers");
    if (tokens == 0) fail("<float_array> is empty");
    last_array = static_cast<long long>(tokens);
  }
}

// assimp's warnings and errors while one file is read: the importers drop data they cannot use
// with only a log line (a glTF face indexing past its vertices: "Some faces had out-of-range
// indices. Those faces were dropped."), which nbvkit refuses. assimp's logger is one per
// process, so reads through it take turns.
class DroppedData : public Assimp::LogStream {
 public:
  DroppedData() : lock_(mutex()) {
    Assimp::DefaultLogger::create("", Assimp::Logger::NORMAL, 0);
    Assimp::DefaultLogger::get()->attachStream(this, Assimp::Logger::Warn | Assimp::Logger::Err);
  }
  ~DroppedData() override {
    Assimp::DefaultLogger::get()->detachStream(this, Assimp::Logger::Warn | Assimp::Logger::Err);
    Assimp::DefaultLogger::kill();
  }
  void write(const char* message) override {
    std::string m = message;  // "Warn,  T0: Some faces ... dropped.\n"
    while (!m.empty() && std::isspace(static_cast<unsigned char>(m.back()))) m.pop_back();
    const std::size_t head = m.find(": ");
    if (head != std::string::npos && head < 16) m.erase(0, head + 2);
    if (m.find("dropped") != std::string::npos && dropped_.size() < 400)
      dropped_ += " " + printable_ascii(m);
  }
  // std::invalid_argument naming what assimp dropped from `path`, if it dropped anything.
  void refuse(const std::string& path) const {
    if (!dropped_.empty())
      throw std::invalid_argument("mesh file '" + path + "' is damaged: assimp read it without" +
                                  " part of its data:" + dropped_);
  }

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  std::lock_guard<std::mutex> lock_;
  std::string dropped_;
};

}  // namespace

Mesh load_mesh(const std::string& path, double scale, char up) {
  if (!std::isfinite(scale) || scale <= 0)
    throw std::invalid_argument("mesh scale must be a positive finite number, got " + fmt(scale));
  if (up != 'z' && up != 'y' && up != 'Z' && up != 'Y')
    throw std::invalid_argument(std::string("mesh up axis must be 'y' or 'z', got '") + up + "'");
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw FileNotFound(path);
  if (fs::is_directory(path, ec))
    throw std::invalid_argument("cannot read mesh '" + path + "': it is a directory");

  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (ext == ".ply") return load_ply_mesh(path, scale, up);
  if (ext == ".obj" || ext == ".off") return load_obj_mesh(path, scale, up, ext == ".off");
  if (ext == ".stl") return load_stl_mesh(path, scale, up);
  const std::string head = read_file_head(path, 4096, "mesh", kMaxMeshFileBytes);
  // A zip archive (zipped Collada, whatever its name) would reach assimp past check_collada's
  // guard: refused, but for 3MF, which is a zip by its format.
  if (ext != ".3mf" && (head.rfind("PK\x03\x04", 0) == 0 || head.rfind("PK\x05\x06", 0) == 0))
    throw std::invalid_argument("cannot read mesh '" + path +
                                "': it is a zip archive (zipped Collada, .zae, or another); "
                                "unzip it and load the mesh file inside");
  if (ext == ".dae" || ext == ".xml" || head.find("<COLLADA") != std::string::npos)
    check_collada(path);

  Assimp::Importer importer;
  auto* io = new RegularFileIOSystem;  // owned by the importer
  importer.SetIOHandler(io);
  const auto refused = [&] {
    if (!io->refused().empty())
      throw std::invalid_argument(
          "cannot read mesh '" + path + "': " +
          (io->refused() == path ? std::string()
                                 : "it refers to '" + printable_ascii(io->refused()) + "': ") +
          io->refused_why());
  };
  // Keep the file's own axes: the caller says which way is up (also for Collada files).
  importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, true);
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE,
                              aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  // Node transforms are applied by place_instances, not by aiProcess_PreTransformVertices.
  const unsigned flags =
      aiProcess_Triangulate | aiProcess_SortByPType | aiProcess_JoinIdenticalVertices;
  // Read first without post-processing: JoinIdenticalVertices would merge a vertex with a NaN
  // coordinate into another vertex (NaN compares equal to nothing, assimp's hashing takes it for
  // a neighbour), and the mesh would load with the wrong shape and area.
  DroppedData dropped;
  const aiScene* scene = importer.ReadFile(path, 0);
  refused();
  dropped.refuse(path);
  if (!scene)
    throw std::invalid_argument("cannot read mesh '" + path +
                                "': " + printable_ascii(importer.GetErrorString()));
  check_finite_vertices(*scene, path);
  const bool has_polygons =
      std::any_of(scene->mMeshes, scene->mMeshes + scene->mNumMeshes, [](const aiMesh* mesh) {
        return std::any_of(mesh->mFaces, mesh->mFaces + mesh->mNumFaces,
                           [](const aiFace& f) { return f.mNumIndices >= 3; });
      });
  if (!has_polygons)  // assimp's post-processing would say "No meshes remaining"
    throw std::invalid_argument("mesh file '" + path +
                                "' contains no triangles (only points or lines, or nothing)");
  scene = importer.ApplyPostProcessing(flags);
  dropped.refuse(path);
  if (!scene)
    throw std::invalid_argument("cannot read mesh '" + path +
                                "': " + printable_ascii(importer.GetErrorString()));

  Points placed;
  Faces faces;
  place_instances(*scene, path, placed, faces);
  check_float32_precision(placed, path, ext, scale);
  return loaded_mesh(std::move(placed), std::move(faces), path, scale, up);
}

}  // namespace nbv
