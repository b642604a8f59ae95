// The one C++ file of drape: a closed triangle mesh in a CGAL AABB tree behind a
// small C interface (include/solid.h). No exception crosses the extern "C" line.
#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/IO/polygon_mesh_io.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/IO/polygon_soup_io.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <solid.h>

typedef CGAL::Exact_predicates_inexact_constructions_kernel K;
typedef K::Point_3                                          Point;
typedef K::Segment_3                                        Segment;
typedef CGAL::Surface_mesh<Point>                           Mesh;
typedef CGAL::AABB_face_graph_triangle_primitive<Mesh>      Primitive;
typedef CGAL::AABB_traits<K, Primitive>                     Traits;
typedef CGAL::AABB_tree<Traits>                             Tree;
typedef CGAL::Side_of_triangle_mesh<Mesh, K>                Side;

struct _p_SolidMesh {
  Mesh                  mesh;
  std::unique_ptr<Tree> tree;
  std::unique_ptr<Side> side;
  double                lo[3], hi[3];
};

// Every closed part of the mesh must enclose a volume: a flat part (a tetrahedron
// with its four corners in a plane, a sheet and its copy turned over) is closed, yet
// has no inside: nothing would hold the cloth there but the contact layer. The
// signed volume of each part (the divergence theorem over its triangles, about the
// part's first vertex) against its box's size: refused below 1e-9 of the cube of the
// box's diagonal (a 1 m plate 1 um thick is 4e-7).
static PetscErrorCode SolidMeshCheckVolume(SolidMesh m, const char *what)
{
  std::vector<std::size_t> part_of;
  std::size_t              nparts = 0;
  bool                     memory = false;

  PetscFunctionBeginUser;
  try {
    auto fcc = m->mesh.add_property_map<Mesh::Face_index, std::size_t>("f:drape_part", 0).first;
    nparts   = CGAL::Polygon_mesh_processing::connected_components(m->mesh, fcc);
    part_of.resize(m->mesh.number_of_faces());
    for (auto f : m->mesh.faces()) part_of[(std::size_t) f] = fcc[f];
    m->mesh.remove_property_map(fcc);
  } catch (const std::bad_alloc &) {
    memory = true;
  }
  PetscCheck(!memory, PETSC_COMM_SELF, PETSC_ERR_MEM, "Out of memory checking the solid %s: this run needs more memory than the machine gives it; use a coarser mesh, or more memory", what);
  std::vector<double>      volume(nparts, 0.0), lo(3 * nparts, HUGE_VAL), hi(3 * nparts, -HUGE_VAL), origin(3 * nparts, 0.0);
  std::vector<std::size_t> nfaces(nparts, 0);
  for (auto f : m->mesh.faces()) {
    const std::size_t c = part_of[(std::size_t) f];
    double            a[3][3];
    int               k = 0;
    for (auto v : CGAL::vertices_around_face(m->mesh.halfedge(f), m->mesh)) {
      const Point &p = m->mesh.point(v);
      a[k][0]        = p.x();
      a[k][1]        = p.y();
      a[k][2]        = p.z();
      k++;
    }
    if (!nfaces[c]++)
      for (int d = 0; d < 3; d++) origin[3 * c + d] = a[0][d];
    for (int i = 0; i < 3; i++)
      for (int d = 0; d < 3; d++) {
        lo[3 * c + d] = std::min(lo[3 * c + d], a[i][d]);
        hi[3 * c + d] = std::max(hi[3 * c + d], a[i][d]);
        a[i][d] -= origin[3 * c + d];
      }
    volume[c] += (a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])) / 6;
  }
  for (std::size_t c = 0; c < nparts; c++) {
    const double diag = std::sqrt((hi[3 * c] - lo[3 * c]) * (hi[3 * c] - lo[3 * c]) + (hi[3 * c + 1] - lo[3 * c + 1]) * (hi[3 * c + 1] - lo[3 * c + 1]) + (hi[3 * c + 2] - lo[3 * c + 2]) * (hi[3 * c + 2] - lo[3 * c + 2]));
    PetscCheck(std::fabs(volume[c]) > 1e-9 * diag * diag * diag, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED,
               "The solid %s encloses no volume: %s (%zu triangles, %.4g m across) is flat, a sheet or faces folded onto each other; drape needs a closed triangle mesh around a solid body", what, nparts > 1 ? "one of its parts" : "it", nfaces[c],
               diag);
  }
  PetscFunctionReturn(0);
}

// Check that the mesh can tell inside from outside; build the tree.
static PetscErrorCode SolidMeshFinish(SolidMesh m, const char *what)
{
  PetscFunctionBeginUser;
  PetscCheck(m->mesh.number_of_faces() > 0, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "The solid %s has no faces; drape needs a closed triangle mesh", what);
  PetscCheck(CGAL::is_triangle_mesh(m->mesh), PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "The solid %s has faces that are not triangles; drape needs a closed triangle mesh (triangulate it first)", what);
  PetscCheck(CGAL::is_closed(m->mesh), PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "The solid %s is not closed (it has border edges); drape needs a closed triangle mesh to tell inside from outside", what);
  for (auto v : m->mesh.vertices()) { /* CGAL's exact predicates trap (SIGFPE) on infinities */
    const Point &p = m->mesh.point(v);
    PetscCheck(std::fabs(p.x()) <= 1e6 && std::fabs(p.y()) <= 1e6 && std::fabs(p.z()) <= 1e6, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED,
               "The solid %s, as placed by -solid_scale, -solid_rotate and -solid_translate, has vertex coordinates that are not finite or beyond 1e6 m", what);
  }
  PetscCall(SolidMeshCheckVolume(m, what));
  try {
    m->tree.reset(new Tree(faces(m->mesh).first, faces(m->mesh).second, m->mesh));
    m->tree->accelerate_distance_queries();
    m->side.reset(new Side(*m->tree));
    CGAL::Bbox_3 b = m->tree->bbox();
    m->lo[0]       = b.xmin();
    m->lo[1]       = b.ymin();
    m->lo[2]       = b.zmin();
    m->hi[0]       = b.xmax();
    m->hi[1]       = b.ymax();
    m->hi[2]       = b.zmax();
  } catch (const std::bad_alloc &) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_MEM, "Out of memory building the AABB tree of the solid %s (%zu triangles): this run needs more memory than the machine gives it; use a coarser mesh, or more memory", what, (size_t) m->mesh.number_of_faces());
  } catch (const std::exception &e) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "CGAL failed to build the AABB tree of the solid %s: %s", what, e.what());
  }
  PetscFunctionReturn(0);
}

// A mesh CGAL's reader refuses, read again as a polygon soup: after a UTF-8
// byte-order mark (which a text editor may put first), and with its faces oriented
// consistently (a mesh with some faces flipped is no halfedge mesh as written). Says
// in `why` what is wrong when it still is no mesh.
static bool ReadAsSoup(const char path[], Mesh &mesh, const char *&why)
{
  std::vector<Point>                    points;
  std::vector<std::vector<std::size_t>> polygons;
  std::string                           name(path), ext;
  std::ifstream                         in(path, std::ios::binary);
  char                                  bom[3] = {0, 0, 0};
  bool                                  ok     = false;

  why = "not a valid OFF, OBJ, STL or PLY polygon mesh";
  if (name.find_last_of('.') != std::string::npos) ext = name.substr(name.find_last_of('.') + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return (char) std::tolower(c); });
  if (!in.read(bom, 3) || (unsigned char) bom[0] != 0xEF || (unsigned char) bom[1] != 0xBB || (unsigned char) bom[2] != 0xBF) in.seekg(0); /* no byte-order mark */
  in.clear();
  if (ext == "off")
    ok = CGAL::IO::read_OFF(in, points, polygons);
  else if (ext == "obj")
    ok = CGAL::IO::read_OBJ(in, points, polygons);
  else if (ext == "stl")
    ok = CGAL::IO::read_STL(in, points, polygons);
  else if (ext == "ply")
    ok = CGAL::IO::read_PLY(in, points, polygons);
  if (!ok || polygons.empty()) return false;
  /* faces flipped against their neighbours are turned (inside and outside, by ray
   * parity, do not depend on which way the whole surface faces) */
  if (!CGAL::Polygon_mesh_processing::orient_polygon_soup(points, polygons)) {
    why = "an edge is shared by more than two faces, or a vertex joins surfaces that meet only there (not a manifold surface); drape needs a closed triangle mesh";
    return false;
  }
  if (!CGAL::Polygon_mesh_processing::is_polygon_soup_a_polygon_mesh(polygons)) {
    why = "its faces do not form a manifold surface; drape needs a closed triangle mesh";
    return false;
  }
  CGAL::Polygon_mesh_processing::polygon_soup_to_polygon_mesh(points, polygons, mesh);
  return true;
}

PetscErrorCode SolidMeshCreateFromFile(const char path[], const PetscReal A[9], const PetscReal b[3], SolidMesh *mesh)
{
  std::unique_ptr<_p_SolidMesh> m;
  bool                          ok = false, memory = false;
  const char                   *why = "not a valid OFF, OBJ, STL or PLY polygon mesh";
  FILE                         *fp  = fopen(path, "r");

  PetscFunctionBeginUser;
  PetscCheck(fp, PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot open the solid mesh file %s", path);
  fclose(fp);
  try {
    m.reset(new _p_SolidMesh);
    ok = CGAL::IO::read_polygon_mesh(std::string(path), m->mesh);
    if (!ok) {
      m->mesh.clear();
      ok = ReadAsSoup(path, m->mesh, why);
    }
  } catch (const std::bad_alloc &) {
    memory = true;
  } catch (const std::exception &e) {
    ok = false;
  }
  PetscCheck(!memory, PETSC_COMM_SELF, PETSC_ERR_MEM, "Out of memory reading the solid mesh file %s: this run needs more memory than the machine gives it; use a coarser mesh, or more memory", path);
  PetscCheck(ok, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "Cannot read the solid mesh file %s: %s", path, why);
  for (auto v : m->mesh.vertices()) {
    const Point &p = m->mesh.point(v);
    double       q[3];
    for (int i = 0; i < 3; i++) q[i] = A[3 * i] * p.x() + A[3 * i + 1] * p.y() + A[3 * i + 2] * p.z() + b[i];
    m->mesh.point(v) = Point(q[0], q[1], q[2]);
  }
  PetscCall(SolidMeshFinish(m.get(), path));
  *mesh = m.release();
  PetscFunctionReturn(0);
}

PetscErrorCode SolidMeshGetBoundingBox(SolidMesh m, PetscReal lo[3], PetscReal hi[3])
{
  PetscFunctionBeginUser;
  for (int i = 0; i < 3; i++) {
    lo[i] = m->lo[i];
    hi[i] = m->hi[i];
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SolidMeshGetSize(SolidMesh m, PetscInt *nv, PetscInt *nt)
{
  PetscFunctionBeginUser;
  if (nv) *nv = (PetscInt) m->mesh.number_of_vertices();
  if (nt) *nt = (PetscInt) m->mesh.number_of_faces();
  PetscFunctionReturn(0);
}

PetscErrorCode SolidMeshGetTriangles(SolidMesh m, PetscReal *xyz)
{
  PetscInt k = 0;

  PetscFunctionBeginUser;
  for (auto f : m->mesh.faces()) {
    for (auto v : CGAL::vertices_around_face(m->mesh.halfedge(f), m->mesh)) {
      const Point &p = m->mesh.point(v);
      xyz[k++]       = p.x();
      xyz[k++]       = p.y();
      xyz[k++]       = p.z();
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SolidMeshQuery(SolidMesh m, const PetscReal p[3], PetscReal closest[3], PetscBool *inside)
{
  PetscFunctionBeginUser;
  try {
    Point q(p[0], p[1], p[2]);
    Point c    = m->tree->closest_point(q);
    closest[0] = c.x();
    closest[1] = c.y();
    closest[2] = c.z();
    *inside    = (*m->side)(q) == CGAL::ON_BOUNDED_SIDE ? PETSC_TRUE : PETSC_FALSE;
  } catch (const std::bad_alloc &) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_MEM, "Out of memory in a distance query to the solid mesh: this run needs more memory than the machine gives it; use a coarser mesh, or more memory");
  } catch (const std::exception &e) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "CGAL query failed: %s", e.what());
  }
  PetscFunctionReturn(0);
}

// The first triangle the segment p0 -> p1 meets: the tree finds the triangles it
// meets (exact predicates), the parameter along it and the triangle's normal are
// computed here in double precision. A segment in a triangle's plane (a particle
// sliding on a face) meets no triangle in this sense.
PetscErrorCode SolidMeshSweep(SolidMesh m, const PetscReal p0[3], const PetscReal p1[3], PetscReal *t, PetscReal normal[3], PetscBool *hit)
{
  std::vector<Mesh::Face_index> faces;
  bool                          memory = false, failed = false;

  PetscFunctionBeginUser;
  *hit = PETSC_FALSE;
  *t   = 1;
  if (p0[0] == p1[0] && p0[1] == p1[1] && p0[2] == p1[2]) PetscFunctionReturn(0);
  try {
    m->tree->all_intersected_primitives(Segment(Point(p0[0], p0[1], p0[2]), Point(p1[0], p1[1], p1[2])), std::back_inserter(faces));
  } catch (const std::bad_alloc &) {
    memory = true;
  } catch (const std::exception &) {
    failed = true;
  }
  PetscCheck(!memory, PETSC_COMM_SELF, PETSC_ERR_MEM, "Out of memory in a swept query to the solid mesh: this run needs more memory than the machine gives it; use a coarser mesh, or more memory");
  PetscCheck(!failed, PETSC_COMM_SELF, PETSC_ERR_LIB, "CGAL failed in a swept query to the solid mesh");
  for (auto f : faces) {
    double a[3][3], e1[3], e2[3], n[3], dn = 0, an = 0;
    int    c = 0;
    for (auto v : CGAL::vertices_around_face(m->mesh.halfedge(f), m->mesh)) {
      const Point &p = m->mesh.point(v);
      a[c][0]        = p.x();
      a[c][1]        = p.y();
      a[c][2]        = p.z();
      c++;
    }
    for (int i = 0; i < 3; i++) {
      e1[i] = a[1][i] - a[0][i];
      e2[i] = a[2][i] - a[0][i];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    for (int i = 0; i < 3; i++) {
      dn += n[i] * (p1[i] - p0[i]);
      an += n[i] * (a[0][i] - p0[i]);
    }
    if (dn == 0) continue; /* in the triangle's plane */
    double s = std::min(1.0, std::max(0.0, an / dn)), l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(l > 0) || (*hit && s >= *t)) continue;
    *hit = PETSC_TRUE;
    *t   = s;
    for (int i = 0; i < 3; i++) normal[i] = (dn > 0 ? -n[i] : n[i]) / l; /* against the motion */
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SolidMeshDestroy(SolidMesh *m)
{
  PetscFunctionBeginUser;
  delete *m;
  *m = nullptr;
  PetscFunctionReturn(0);
}
