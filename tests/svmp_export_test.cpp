// The svMultiPhysics case `baffle export-svmp` writes (issue 7), read with VTK's own XML
// readers and checked the way svMultiPhysics relies on it: Int32 1-based GlobalNodeID /
// GlobalElementID, face points that are volume nodes with bit-identical coordinates,
// each face triangle's GlobalElementID a tetrahedron having that triangle, and
// mesh-complete.exterior.vtp / walls_combined.vtp made of exactly the right faces.
// Cases: a box of tetrahedra with two interior planes made here (no gmsh), and the
// phantom designed and meshed by `baffle` (gmsh; skipped with BAFFLE_SKIP_GMSH=1).
// Usage: baffle_svmp_export_test export_box | export_phantom | corrupted_copies_fail
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkIdList.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

using Triangle = std::array<int, 3>;  // sorted GlobalNodeIDs

void require(bool condition, const std::string& what) {
  if (!condition) throw std::runtime_error(what);
}

// ----------------------------------------------------------------------------------
// The case: a 5 x 5 x 15 mm box of Kuhn tetrahedra, interior nodes moved off the grid
// (so the mm -> cm conversion gives coordinates that are not round numbers), written as
// `baffle mesh` writes a mesh: volume .vtu and faces .vtp with ModelFaceID and a
// 1-based GlobalNodeID.
// ----------------------------------------------------------------------------------

constexpr int kNx = 2, kNy = 2, kNz = 6;
constexpr double kH = 2.5;
constexpr int kWallA = 1, kInlet = 2, kOutlet = 3, kWallB = 4, kPlane1 = 10, kPlane2 = 11;

// The face files export-svmp writes for a case (named by role), and which are walls.
struct Faces {
  std::vector<std::string> names;
  std::set<std::string> walls;
};
const Faces kBoxFaces = {{"wall_1", "inflow", "outlet_3", "wall_4", "plane_10", "plane_11"}, {"wall_1", "wall_4"}};
const Faces kPhantomFaces = {{"wall_2", "wall_10", "inflow", "outlet_16"}, {"wall_2", "wall_10"}};
constexpr int kSkipCode = BAFFLE_SKIP_CODE;

struct Skip {
  std::string why;
};

int node(int i, int j, int k) { return i + (kNx + 1) * (j + (kNy + 1) * k); }

std::array<double, 3> grid_point(int i, int j, int k) {
  std::array<double, 3> p{i * kH, j * kH, k * kH};
  const int n = node(i, j, k);
  const bool inner[3] = {0 < i && i < kNx, 0 < j && j < kNy, 0 < k && k < kNz};
  for (int c = 0; c < 3; ++c) {
    if (inner[c]) p[c] += 0.05 * kH * std::sin(12.9898 * n + 78.233 * c);
  }
  return p;
}

double signed_volume(const std::vector<std::array<double, 3>>& x, const std::array<int, 4>& t) {
  double a[3], b[3], c[3];
  for (int d = 0; d < 3; ++d) {
    a[d] = x[t[1]][d] - x[t[0]][d];
    b[d] = x[t[2]][d] - x[t[0]][d];
    c[d] = x[t[3]][d] - x[t[0]][d];
  }
  return (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0;
}

struct BoxMesh {
  std::vector<std::array<double, 3>> points;
  std::vector<std::array<int, 4>> tets;
  std::map<int, std::vector<std::array<int, 3>>> faces;  // ModelFaceID -> triangles (0-based)
};

// The face a boundary triangle lies on, from the grid indices of its corners.
int boundary_face(const std::array<int, 3>& tri) {
  auto all = [&](const std::function<bool(int, int, int)>& on) {
    return std::all_of(tri.begin(), tri.end(), [&](int v) {
      return on(v % (kNx + 1), (v / (kNx + 1)) % (kNy + 1), v / ((kNx + 1) * (kNy + 1)));
    });
  };
  if (all([](int, int, int k) { return k == 0; })) return kInlet;
  if (all([](int, int, int k) { return k == kNz; })) return kOutlet;
  if (all([](int i, int, int) { return i == 0; }) || all([](int, int j, int) { return j == 0; })) return kWallA;
  return kWallB;
}

BoxMesh box_mesh() {
  BoxMesh m;
  for (int k = 0; k <= kNz; ++k)
    for (int j = 0; j <= kNy; ++j)
      for (int i = 0; i <= kNx; ++i) m.points.push_back(grid_point(i, j, k));
  const int orders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < kNz; ++k)
    for (int j = 0; j < kNy; ++j)
      for (int i = 0; i < kNx; ++i)
        for (const auto& order : orders) {
          int c[3] = {i, j, k};
          std::array<int, 4> tet{node(i, j, k), 0, 0, 0};
          for (int n = 0; n < 3; ++n) {
            ++c[order[n]];
            tet[n + 1] = node(c[0], c[1], c[2]);
          }
          if (signed_volume(m.points, tet) < 0) std::swap(tet[2], tet[3]);
          m.tets.push_back(tet);
        }
  // Every tet face, wound outward from its tet: count 1 = boundary, 2 = interior.
  std::map<Triangle, std::pair<int, std::array<int, 3>>> uses;
  for (const auto& t : m.tets) {
    const std::array<std::array<int, 3>, 4> outward = {{{t[1], t[2], t[3]}, {t[0], t[3], t[2]}, {t[0], t[1], t[3]}, {t[0], t[2], t[1]}}};
    for (const auto& f : outward) {
      Triangle key = f;
      std::sort(key.begin(), key.end());
      auto& use = uses[key];
      use.first += 1;
      use.second = f;
    }
  }
  for (const auto& [key, use] : uses) {
    const int layer = key[0] / ((kNx + 1) * (kNy + 1));
    const bool flat = layer == key[2] / ((kNx + 1) * (kNy + 1));
    if (use.first == 1) {
      m.faces[boundary_face(use.second)].push_back(use.second);
    } else if (flat && (layer == 2 || layer == 4)) {
      m.faces[layer == 2 ? kPlane1 : kPlane2].push_back(use.second);
    }
  }
  return m;
}

vtkSmartPointer<vtkIntArray> int_array(const char* name, const std::vector<int>& values) {
  auto a = vtkSmartPointer<vtkIntArray>::New();
  a->SetName(name);
  for (int v : values) a->InsertNextValue(v);
  return a;
}

vtkSmartPointer<vtkPoints> double_points(const std::vector<std::array<double, 3>>& points) {
  auto p = vtkSmartPointer<vtkPoints>::New();
  p->SetDataTypeToDouble();
  for (const auto& x : points) p->InsertNextPoint(x.data());
  return p;
}

template <class Writer, class Data>
void write_xml(Data* data, const fs::path& path) {
  vtkNew<Writer> writer;
  writer->SetFileName(path.string().c_str());
  writer->SetInputData(data);
  require(writer->Write() == 1, "cannot write " + path.string());
}

// mesh.vtu and mesh-faces.vtp of the box, and case.json naming the faces' roles.
void write_box_case(const fs::path& dir) {
  const BoxMesh m = box_mesh();
  vtkNew<vtkUnstructuredGrid> volume;
  volume->SetPoints(double_points(m.points));
  for (const auto& t : m.tets) {
    const vtkIdType ids[4] = {t[0], t[1], t[2], t[3]};
    volume->InsertNextCell(VTK_TETRA, 4, ids);
  }
  write_xml<vtkXMLUnstructuredGridWriter>(volume.Get(), dir / "mesh.vtu");
  vtkNew<vtkPolyData> faces;
  vtkNew<vtkCellArray> triangles;
  std::vector<int> face_ids;
  for (const auto& [id, tris] : m.faces) {
    for (const auto& t : tris) {
      const vtkIdType ids[3] = {t[0], t[1], t[2]};
      triangles->InsertNextCell(3, ids);
      face_ids.push_back(id);
    }
  }
  // All volume points, GlobalNodeID = index + 1 (the faces use a subset; that is allowed).
  std::vector<int> node_ids(m.points.size());
  for (std::size_t i = 0; i < node_ids.size(); ++i) node_ids[i] = static_cast<int>(i) + 1;
  faces->SetPoints(double_points(m.points));
  faces->SetPolys(triangles);
  faces->GetPointData()->AddArray(int_array("GlobalNodeID", node_ids));
  faces->GetCellData()->AddArray(int_array("ModelFaceID", face_ids));
  write_xml<vtkXMLPolyDataWriter>(faces.Get(), dir / "mesh-faces.vtp");
  std::ofstream(dir / "case.json") << R"({
  "mesh": { "volume": "mesh.vtu", "units": "mm" },
  "faces": { "inlet": 2, "outlets": [3], "planes": [10, 11] },
  "inflow": { "q_mean_ml_s": 21.46 },
  "outlet": { "resistance_dyn_s_cm5": 5467 },
  "time": { "dt_s": 0.01, "cycles": 1 }
})";
}

fs::path baffle_cli() {
  const char* env = std::getenv("BAFFLE_CLI");
  return env != nullptr && env[0] != '\0' ? fs::path(env) : fs::path(BAFFLE_CLI_EXECUTABLE);
}

// Run `baffle <arguments>` (each argument quoted), its output in dir/<log>; throws with
// that output when it fails.
void run_baffle(const std::vector<std::string>& arguments, const fs::path& log) {
  std::string command = "\"" + baffle_cli().string() + "\"";
  for (const std::string& a : arguments) command += " \"" + a + "\"";
  command += " > \"" + log.string() + "\" 2>&1";
  if (std::system(command.c_str()) != 0) {
    std::ifstream text(log);
    std::cerr << text.rdbuf();
    throw std::runtime_error("failed: " + command);
  }
}

fs::path fresh(const fs::path& dir) {
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// `baffle export-svmp` of dir/case.json into dir/svmp; returns that directory.
fs::path export_case(const fs::path& dir) {
  const fs::path out = dir / "svmp";
  run_baffle({"export-svmp", (dir / "case.json").string(), "--out", out.string()}, dir / "export.log");
  return out;
}

fs::path export_box_case(const fs::path& dir) {
  write_box_case(fresh(dir));
  return export_case(dir);
}

// The phantom designed, meshed coarsely (2 mm) and exported as `baffle simulate` takes it.
fs::path export_phantom_case(const fs::path& dir) {
  const char* skip = std::getenv("BAFFLE_SKIP_GMSH");
  if (skip != nullptr && std::string(skip) == "1") throw Skip{"BAFFLE_SKIP_GMSH=1: no gmsh mesh of the phantom"};
  fresh(dir);
  run_baffle({"design", "--phantom", "--out", (dir / "design").string()}, dir / "design.log");
  run_baffle({"mesh", "--surface", (dir / "design" / "domain.vtp").string(), "--edge-length-mm", "2.0", "--out",
              (dir / "mesh.vtu").string()},
             dir / "mesh.log");
  std::ofstream(dir / "case.json") << R"({
  "mesh": { "volume": "mesh.vtu", "units": "mm" },
  "faces": { "inlet": 11, "outlets": [16], "walls": [2, 10] },
  "inflow": { "bsa_m2": 0.37, "cardiac_index_l_min_m2": 3.48 },
  "outlet": { "sbp_mmhg": 107, "dbp_mmhg": 78 },
  "time": { "dt_s": 0.001, "cycles": 1 }
})";
  return export_case(dir);
}

// ----------------------------------------------------------------------------------
// The check: every problem found, as text naming the file (empty = the case is right).
// ----------------------------------------------------------------------------------

struct Problems {
  std::vector<std::string> list;
  void add(const fs::path& file, const std::string& what) { list.push_back(file.filename().string() + ": " + what); }
};

// An Int32 (vtkIntArray, one component) array, or null with a problem.
vtkIntArray* int32_array(vtkFieldData* data, const char* name, const fs::path& file, Problems& problems) {
  vtkAbstractArray* array = data->GetAbstractArray(name);
  if (array == nullptr) {
    problems.add(file, std::string("no array ") + name);
    return nullptr;
  }
  auto* ints = vtkIntArray::SafeDownCast(array);
  if (ints == nullptr || array->GetDataType() != VTK_INT || array->GetNumberOfComponents() != 1) {
    problems.add(file, std::string(name) + " is " + array->GetDataTypeAsString() + " x" +
                           std::to_string(array->GetNumberOfComponents()) + ", not Int32");
    return nullptr;
  }
  return ints;
}

bool in_range(int id, vtkIdType n) { return id >= 1 && id <= n; }

struct Volume {
  vtkSmartPointer<vtkUnstructuredGrid> grid;
  std::vector<vtkIdType> point_of_node;                 // GlobalNodeID - 1 -> point
  std::vector<std::array<int, 4>> tet_of_element;       // GlobalElementID - 1 -> node ids
  std::map<Triangle, int> tets_having;                  // tet faces -> how many tets
};

// The file read with VTK's XML reader, or null with a problem (missing, unreadable, empty).
template <class Reader, class Data>
vtkSmartPointer<Data> read_xml(const fs::path& path, Problems& problems) {
  if (!fs::is_regular_file(path)) {
    problems.add(path, "missing");
    return nullptr;
  }
  vtkNew<Reader> reader;
  reader->SetFileName(path.string().c_str());
  reader->Update();
  if (reader->GetErrorCode() != 0 || reader->GetOutput()->GetNumberOfCells() == 0) {
    problems.add(path, "unreadable or empty");
    return nullptr;
  }
  return vtkSmartPointer<Data>(reader->GetOutput());
}

// The volume's ids: each a permutation of 1..n, every cell a tetrahedron.
bool read_volume(const fs::path& path, Volume& v, Problems& problems) {
  v.grid = read_xml<vtkXMLUnstructuredGridReader, vtkUnstructuredGrid>(path, problems);
  if (v.grid == nullptr) return false;
  vtkIntArray* nodes = int32_array(v.grid->GetPointData(), "GlobalNodeID", path, problems);
  vtkIntArray* elements = int32_array(v.grid->GetCellData(), "GlobalElementID", path, problems);
  if (nodes == nullptr || elements == nullptr) return false;
  const vtkIdType n_points = v.grid->GetNumberOfPoints(), n_cells = v.grid->GetNumberOfCells();
  v.point_of_node.assign(n_points, -1);
  for (vtkIdType p = 0; p < n_points; ++p) {
    const int id = nodes->GetValue(p);
    if (!in_range(id, n_points) || v.point_of_node[id - 1] != -1) {
      problems.add(path, "GlobalNodeID " + std::to_string(id) + " outside 1.." + std::to_string(n_points) + " or repeated");
      return false;
    }
    v.point_of_node[id - 1] = p;
  }
  v.tet_of_element.assign(n_cells, {0, 0, 0, 0});
  std::vector<bool> seen(n_cells, false);
  vtkNew<vtkIdList> corners;
  for (vtkIdType c = 0; c < n_cells; ++c) {
    const int id = elements->GetValue(c);
    if (!in_range(id, n_cells) || seen[id - 1] || v.grid->GetCellType(c) != VTK_TETRA) {
      problems.add(path, "cell " + std::to_string(c) + ": GlobalElementID " + std::to_string(id) + " outside 1.." +
                             std::to_string(n_cells) + ", repeated, or not a tetrahedron");
      return false;
    }
    seen[id - 1] = true;
    v.grid->GetCellPoints(c, corners);
    for (int k = 0; k < 4; ++k) v.tet_of_element[id - 1][k] = nodes->GetValue(corners->GetId(k));
    const auto& t = v.tet_of_element[id - 1];
    for (int skip = 0; skip < 4; ++skip) {
      Triangle f;
      for (int k = 0, m = 0; k < 4; ++k)
        if (k != skip) f[m++] = t[k];
      std::sort(f.begin(), f.end());
      ++v.tets_having[f];
    }
  }
  return true;
}

struct Surface {
  std::map<Triangle, int> triangles;  // -> ModelFaceID (0 when not written)
};

// A face-like file: its points are volume nodes with the very same coordinate bits,
// each triangle's GlobalElementID a tetrahedron that has the triangle as a face.
Surface read_surface(const fs::path& path, const Volume& v, Problems& problems) {
  Surface s;
  auto poly = read_xml<vtkXMLPolyDataReader, vtkPolyData>(path, problems);
  if (poly == nullptr) return s;
  vtkIntArray* nodes = int32_array(poly->GetPointData(), "GlobalNodeID", path, problems);
  vtkIntArray* elements = int32_array(poly->GetCellData(), "GlobalElementID", path, problems);
  vtkIntArray* face_ids = nullptr;
  if (poly->GetCellData()->GetAbstractArray("ModelFaceID") != nullptr)
    face_ids = int32_array(poly->GetCellData(), "ModelFaceID", path, problems);
  if (nodes == nullptr || elements == nullptr) return s;
  if (poly->GetPoints()->GetDataType() != v.grid->GetPoints()->GetDataType())
    problems.add(path, "points are not stored in the volume's type");
  const vtkIdType n_nodes = v.grid->GetNumberOfPoints();
  for (vtkIdType p = 0; p < poly->GetNumberOfPoints(); ++p) {
    const int id = nodes->GetValue(p);
    if (!in_range(id, n_nodes)) {
      problems.add(path, "point " + std::to_string(p) + ": GlobalNodeID " + std::to_string(id) + " outside 1.." +
                             std::to_string(n_nodes));
      return s;
    }
    double here[3], there[3];
    poly->GetPoint(p, here);
    v.grid->GetPoint(v.point_of_node[id - 1], there);
    if (std::memcmp(here, there, sizeof here) != 0)
      problems.add(path, "point " + std::to_string(p) + ": coordinates differ from volume node " + std::to_string(id));
  }
  vtkNew<vtkIdList> corners;
  for (vtkIdType c = 0; c < poly->GetNumberOfCells(); ++c) {
    poly->GetCellPoints(c, corners);
    const int element = elements->GetValue(c);
    if (poly->GetCellType(c) != VTK_TRIANGLE || !in_range(element, static_cast<vtkIdType>(v.tet_of_element.size()))) {
      problems.add(path, "cell " + std::to_string(c) + ": not a triangle, or GlobalElementID " + std::to_string(element) +
                             " outside 1.." + std::to_string(v.tet_of_element.size()));
      continue;
    }
    Triangle tri;
    for (int k = 0; k < 3; ++k) tri[k] = nodes->GetValue(corners->GetId(k));
    const auto& tet = v.tet_of_element[element - 1];
    const bool has = std::all_of(tri.begin(), tri.end(), [&](int n) { return std::find(tet.begin(), tet.end(), n) != tet.end(); });
    if (!has)
      problems.add(path, "cell " + std::to_string(c) + ": GlobalElementID " + std::to_string(element) +
                             " is a tetrahedron that does not have this triangle");
    std::sort(tri.begin(), tri.end());
    s.triangles[tri] = face_ids != nullptr ? face_ids->GetValue(c) : 0;
  }
  return s;
}

std::set<Triangle> keys(const std::map<Triangle, int>& m) {
  std::set<Triangle> out;
  for (const auto& kv : m) out.insert(kv.first);
  return out;
}

// The whole mesh-complete/ of an exported case.
std::vector<std::string> check_mesh_complete(const fs::path& case_dir, const Faces& expected) {
  Problems problems;
  const fs::path mesh = case_dir / "mesh-complete";
  Volume v;
  if (!read_volume(mesh / "mesh-complete.mesh.vtu", v, problems)) return problems.list;
  std::map<Triangle, int> boundary_faces, wall_faces;  // from the face files
  const fs::path surfaces = mesh / "mesh-surfaces";
  std::set<std::string> written;
  for (const auto& entry : fs::directory_iterator(surfaces)) written.insert(entry.path().stem().string());
  if (written != std::set<std::string>(expected.names.begin(), expected.names.end()))
    problems.add(surfaces, "does not hold exactly one .vtp per face of the case");
  for (const std::string& name : expected.names) {
    const fs::path path = surfaces / (name + ".vtp");
    const Surface face = read_surface(path, v, problems);
    std::set<int> face_ids;
    int interior = 0;
    for (const auto& [tri, id] : face.triangles) {
      face_ids.insert(id);
      interior += v.tets_having.count(tri) != 0 && v.tets_having.at(tri) == 2;
      if (v.tets_having.count(tri) == 0) problems.add(path, "a triangle that is no tetrahedron's face");
    }
    if (face_ids.size() > 1) problems.add(path, "more than one ModelFaceID");
    if (interior != 0 && interior != static_cast<int>(face.triangles.size()))
      problems.add(path, "mixes boundary and interior triangles");
    if (interior == 0) boundary_faces.insert(face.triangles.begin(), face.triangles.end());
    if (expected.walls.count(name) != 0) wall_faces.insert(face.triangles.begin(), face.triangles.end());
  }
  std::set<Triangle> volume_boundary;
  for (const auto& [tri, n] : v.tets_having)
    if (n == 1) volume_boundary.insert(tri);
  const fs::path exterior_path = mesh / "mesh-complete.exterior.vtp";
  const Surface exterior = read_surface(exterior_path, v, problems);
  if (keys(exterior.triangles) != volume_boundary)
    problems.add(exterior_path, "is not the boundary of the volume");
  if (exterior.triangles != boundary_faces)
    problems.add(exterior_path, "is not the boundary face files together (triangles or ModelFaceIDs differ)");
  const fs::path walls_path = mesh / "walls_combined.vtp";
  const Surface walls = read_surface(walls_path, v, problems);
  if (walls.triangles != wall_faces) problems.add(walls_path, "is not the wall faces together");
  return problems.list;
}

std::string joined(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& line : lines) out += "\n  " + line;
  return out;
}

fs::path scratch(const std::string& name) { return fs::temp_directory_path() / ("baffle-svmp-ctest-" + name); }

void check_exported(const fs::path& dir, const Faces& faces) {
  const std::vector<std::string> problems = check_mesh_complete(dir, faces);
  require(problems.empty(), "the exported case has problems:" + joined(problems));
  std::cout << "checked " << dir << ": " << faces.names.size() << " faces, exterior and walls\n";
}

void export_box() { check_exported(export_box_case(scratch("export")), kBoxFaces); }

void export_phantom() { check_exported(export_phantom_case(scratch("phantom")), kPhantomFaces); }

// ----------------------------------------------------------------------------------
// The check must fail on a case that is wrong: one corruption per copy of a good case.
// ----------------------------------------------------------------------------------

vtkSmartPointer<vtkPolyData> load_vtp(const fs::path& path) {
  vtkNew<vtkXMLPolyDataReader> reader;
  reader->SetFileName(path.string().c_str());
  reader->Update();
  return reader->GetOutput();
}

void edit_vtp(const fs::path& path, const std::function<void(vtkPolyData*)>& edit) {
  auto poly = load_vtp(path);
  edit(poly);
  write_xml<vtkXMLPolyDataWriter>(poly.Get(), path);
}

void edit_vtu(const fs::path& path, const std::function<void(vtkUnstructuredGrid*)>& edit) {
  vtkNew<vtkXMLUnstructuredGridReader> reader;
  reader->SetFileName(path.string().c_str());
  reader->Update();
  vtkSmartPointer<vtkUnstructuredGrid> grid = reader->GetOutput();
  edit(grid);
  write_xml<vtkXMLUnstructuredGridWriter>(grid.Get(), path);
}

// The id of a tetrahedron that does not have triangle 0 of `poly`.
int tet_without_first_triangle(const fs::path& volume_path, vtkPolyData* poly) {
  Problems ignored;
  Volume v;
  require(read_volume(volume_path, v, ignored), "cannot read the good volume");
  auto* nodes = vtkIntArray::SafeDownCast(poly->GetPointData()->GetArray("GlobalNodeID"));
  vtkNew<vtkIdList> corners;
  poly->GetCellPoints(0, corners);
  for (std::size_t e = 0; e < v.tet_of_element.size(); ++e) {
    const auto& tet = v.tet_of_element[e];
    int shared = 0;
    for (int k = 0; k < 3; ++k) shared += std::count(tet.begin(), tet.end(), nodes->GetValue(corners->GetId(k)));
    if (shared < 3) return static_cast<int>(e) + 1;
  }
  throw std::runtime_error("every tetrahedron has the triangle");
}

struct Corruption {
  std::string name;
  std::string expected;  // text the check must report
  std::function<void(const fs::path& mesh)> apply;
};

std::vector<Corruption> corruptions() {
  const auto surface = [](const std::string& name) { return fs::path("mesh-surfaces") / (name + ".vtp"); };
  return {
      {"coordinate one ulp off", "inflow.vtp: point 0: coordinates differ",
       [=](const fs::path& m) {
         edit_vtp(m / surface("inflow"), [](vtkPolyData* p) {
           double x[3];
           p->GetPoint(0, x);
           x[0] = std::nextafter(x[0], 1e9);
           p->GetPoints()->SetPoint(0, x);
         });
       }},
      {"element without the triangle", "plane_10.vtp: cell 0: GlobalElementID",
       [=](const fs::path& m) {
         edit_vtp(m / surface("plane_10"), [&](vtkPolyData* p) {
           const int other = tet_without_first_triangle(m / "mesh-complete.mesh.vtu", p);
           vtkIntArray::SafeDownCast(p->GetCellData()->GetArray("GlobalElementID"))->SetValue(0, other);
         });
       }},
      {"element id past the end", "outlet_3.vtp: cell 0: not a triangle, or GlobalElementID 1073741824 outside",
       [=](const fs::path& m) {
         edit_vtp(m / surface("outlet_3"), [](vtkPolyData* p) {
           vtkIntArray::SafeDownCast(p->GetCellData()->GetArray("GlobalElementID"))->SetValue(0, 1 << 30);
         });
       }},
      {"0-based node ids", "mesh-complete.mesh.vtu: GlobalNodeID 0 outside",
       [=](const fs::path& m) {
         edit_vtu(m / "mesh-complete.mesh.vtu", [](vtkUnstructuredGrid* g) {
           auto* ids = vtkIntArray::SafeDownCast(g->GetPointData()->GetArray("GlobalNodeID"));
           for (vtkIdType k = 0; k < ids->GetNumberOfTuples(); ++k) ids->SetValue(k, ids->GetValue(k) - 1);
         });
       }},
      {"Float64 node ids", "wall_4.vtp: GlobalNodeID is double",
       [=](const fs::path& m) {
         edit_vtp(m / surface("wall_4"), [](vtkPolyData* p) {
           vtkDataArray* ints = p->GetPointData()->GetArray("GlobalNodeID");
           vtkNew<vtkDoubleArray> doubles;
           doubles->DeepCopy(ints);
           doubles->SetName("GlobalNodeID");
           p->GetPointData()->RemoveArray("GlobalNodeID");
           p->GetPointData()->AddArray(doubles);
         });
       }},
      {"Float64 ModelFaceID", "inflow.vtp: ModelFaceID is double",
       [=](const fs::path& m) {
         edit_vtp(m / surface("inflow"), [](vtkPolyData* p) {
           vtkNew<vtkDoubleArray> doubles;
           doubles->DeepCopy(p->GetCellData()->GetArray("ModelFaceID"));
           doubles->SetName("ModelFaceID");
           p->GetCellData()->RemoveArray("ModelFaceID");
           p->GetCellData()->AddArray(doubles);
         });
       }},
      {"walls_combined missing", "walls_combined.vtp: missing",
       [](const fs::path& m) { fs::remove(m / "walls_combined.vtp"); }},
      {"exterior without a triangle", "mesh-complete.exterior.vtp: is not the boundary of the volume",
       [](const fs::path& m) {
         edit_vtp(m / "mesh-complete.exterior.vtp", [](vtkPolyData* p) {
           vtkNew<vtkPolyData> rest;
           rest->SetPoints(p->GetPoints());
           rest->GetPointData()->ShallowCopy(p->GetPointData());
           rest->GetCellData()->CopyAllocate(p->GetCellData());
           vtkNew<vtkCellArray> polys;
           vtkNew<vtkIdList> ids;
           for (vtkIdType c = 1; c < p->GetNumberOfCells(); ++c) {
             p->GetCellPoints(c, ids);
             polys->InsertNextCell(ids);
             rest->GetCellData()->CopyData(p->GetCellData(), c, c - 1);
           }
           rest->SetPolys(polys);
           p->ShallowCopy(rest);
         });
       }},
      {"walls_combined with the inlet's ModelFaceID on a wall", "walls_combined.vtp: is not the wall faces together",
       [](const fs::path& m) {
         edit_vtp(m / "walls_combined.vtp", [](vtkPolyData* p) {
           vtkIntArray::SafeDownCast(p->GetCellData()->GetArray("ModelFaceID"))->SetValue(0, kInlet);
         });
       }},
  };
}

void corrupted_copies_fail() {
  const fs::path good = export_box_case(scratch("corrupt-source"));
  const std::vector<std::string> clean = check_mesh_complete(good, kBoxFaces);
  require(clean.empty(), "the uncorrupted case already has problems:" + joined(clean));
  const fs::path copy = scratch("corrupt-copy");
  for (const Corruption& c : corruptions()) {
    fs::remove_all(copy);
    fs::copy(good, copy, fs::copy_options::recursive);
    c.apply(copy / "mesh-complete");
    const std::vector<std::string> problems = check_mesh_complete(copy, kBoxFaces);
    const bool found = std::any_of(problems.begin(), problems.end(),
                                   [&](const std::string& p) { return p.find(c.expected) != std::string::npos; });
    require(found, "corruption '" + c.name + "' not reported as '" + c.expected + "'; reported:" + joined(problems));
    std::cout << "detected " << c.name << ": " << problems.front() << "\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::map<std::string, std::function<void()>> cases = {
      {"export_box", export_box}, {"export_phantom", export_phantom}, {"corrupted_copies_fail", corrupted_copies_fail}};
  if (argc != 2 || cases.count(argv[1]) == 0) {
    std::cerr << "usage: baffle_svmp_export_test export_box|export_phantom|corrupted_copies_fail\n";
    return 2;
  }
  try {
    cases.at(argv[1])();
    return 0;
  } catch (const Skip& skip) {
    std::cout << "SKIPPED: " << skip.why << "\n";
    return kSkipCode;
  } catch (const std::exception& e) {
    std::cerr << "FAILED " << argv[1] << ": " << e.what() << "\n";
    return 1;
  }
}
