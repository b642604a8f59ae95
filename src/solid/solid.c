/* The rigid solid: a body from a mesh file (a CGAL AABB tree) or a generated
 * primitive (box, sphere, cylinder: exact closed-form distance, no tree; the
 * triangulated primitive serves pictures only), and a plane. */
#include <solid.h>
#include <petscviewer.h>
#include <drape.h>

typedef enum {
  SOLID_NONE,
  SOLID_MESH,
  SOLID_BOX,
  SOLID_SPHERE,
  SOLID_CYLINDER
} SolidType;
static const char *const solid_type_names[] = {"none", "mesh", "box", "sphere", "cylinder", "SolidType", "SOLID_", NULL};

struct _p_Solid {
  MPI_Comm   comm;
  SolidType  type;
  char       file[PETSC_MAX_PATH_LEN];
  PetscReal  scale, rotate[3], translate[3], size[3], radius, height;
  PetscInt   resolution;
  PetscBool  has_plane;
  PetscReal  plane[4];     /* n.x = offset, outside where n.x > offset; n unit */
  SolidMesh  mesh;         /* -solid_type mesh */
  PetscReal  R[9];         /* primitives: rotation (body to world), with scale and translate */
  PetscInt   ntri;         /* primitives: triangles for pictures */
  PetscReal *tri;          /* 9 reals each, world coordinates */
  PetscReal  lo[3], hi[3]; /* the body's box */
};

PetscErrorCode SolidCreate(MPI_Comm comm, Solid *solid)
{
  Solid s;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&s));
  s->comm       = comm;
  s->scale      = 1.0;
  s->size[0]    = 1.0;
  s->size[1]    = 1.0;
  s->size[2]    = 0.75;
  s->radius     = 0.25;
  s->height     = 0.5;
  s->resolution = 32;
  *solid        = s;
  PetscFunctionReturn(0);
}

PetscErrorCode SolidSetFromOptions(Solid s)
{
  PetscInt  itype = (PetscInt) s->type, n;
  PetscBool set, fileset, floorset;
  PetscReal floor_z = 0;

  PetscFunctionBeginUser;
  PetscOptionsBegin(s->comm, NULL, "Solid: the rigid body the cloth drapes over", "Solid");
  PetscCall(PetscOptionsEList("-solid_type", "Body: none, mesh (-solid_file), box, sphere, cylinder", "SolidSetFromOptions", solid_type_names, 5, solid_type_names[itype], &itype, &set));
  PetscCall(PetscOptionsString("-solid_file", "Closed triangle mesh file (OFF, OBJ, STL, PLY) for -solid_type mesh", "SolidSetFromOptions", s->file, s->file, sizeof s->file, &fileset));
  PetscCall(PetscOptionsReal("-solid_scale", "Uniform scale of the body (before rotation and translation)", "SolidSetFromOptions", s->scale, &s->scale, NULL));
  n = 3;
  PetscCall(PetscOptionsRealArray("-solid_rotate", "Rotation of the body about x, then y, then z (degrees)", "SolidSetFromOptions", s->rotate, &n, &set));
  PetscCheck(!set || n == 3, s->comm, PETSC_ERR_USER_INPUT, "-solid_rotate needs three angles ax,ay,az in degrees");
  n = 3;
  PetscCall(PetscOptionsRealArray("-solid_translate", "Translation of the body x,y,z (m)", "SolidSetFromOptions", s->translate, &n, &set));
  PetscCheck(!set || n == 3, s->comm, PETSC_ERR_USER_INPUT, "-solid_translate needs three components x,y,z");
  n = 3;
  PetscCall(PetscOptionsRealArray("-solid_size", "Box edge lengths sx,sy,sz (m), centred at the origin", "SolidSetFromOptions", s->size, &n, &set));
  PetscCheck(!set || n == 3, s->comm, PETSC_ERR_USER_INPUT, "-solid_size needs three lengths sx,sy,sz");
  PetscCall(PetscOptionsReal("-solid_radius", "Sphere or cylinder radius (m)", "SolidSetFromOptions", s->radius, &s->radius, NULL));
  PetscCall(PetscOptionsReal("-solid_height", "Cylinder height along z (m), centred at the origin", "SolidSetFromOptions", s->height, &s->height, NULL));
  PetscCall(PetscOptionsInt("-solid_resolution", "Segments around a generated sphere or cylinder in pictures (contact uses the exact shape)", "SolidSetFromOptions", s->resolution, &s->resolution, NULL));
  n = 4;
  PetscCall(PetscOptionsRealArray("-solid_plane", "Plane nx,ny,nz,d: the solid fills n.x < d", "SolidSetFromOptions", s->plane, &n, &s->has_plane));
  PetscCheck(!s->has_plane || n == 4, s->comm, PETSC_ERR_USER_INPUT, "-solid_plane needs four numbers nx,ny,nz,d (the solid fills n.x < d)");
  PetscCall(PetscOptionsReal("-solid_floor", "A horizontal floor at this height (m): same as -solid_plane 0,0,1,z", "SolidSetFromOptions", floor_z, &floor_z, &floorset));
  PetscOptionsEnd();
  s->type = (SolidType) itype;
  if (fileset && s->type == SOLID_NONE) s->type = SOLID_MESH;
  PetscCheck(s->type != SOLID_MESH || s->file[0], s->comm, PETSC_ERR_USER_INPUT, "-solid_type mesh needs -solid_file FILE (OFF, OBJ, STL or PLY)");
  PetscCheck(!fileset || s->type == SOLID_MESH, s->comm, PETSC_ERR_USER_INPUT, "-solid_file is used only with -solid_type mesh");
  PetscCall(DrapeCheckPathLength(s->comm, "-solid_file", s->file, sizeof s->file));
  if (s->type == SOLID_MESH) PetscCall(DrapeCheckInputFile(s->comm, "-solid_file", "solid mesh"));
  if (s->type == SOLID_MESH) PetscCall(DrapeRegisterInput(s->file, "solid mesh")); /* read at set-up: no output may be it */
  /* placements and sizes no real scene approaches: CGAL's exact arithmetic traps on overflow */
  PetscCall(DrapeCheckReal(s->comm, "-solid_scale", 1, &s->scale, 1e-6, 1e6, ""));
  PetscCall(DrapeCheckReal(s->comm, "-solid_rotate", 3, s->rotate, -360, 360, "degrees"));
  PetscCall(DrapeCheckReal(s->comm, "-solid_translate", 3, s->translate, -1e4, 1e4, "m"));
  PetscCall(DrapeCheckReal(s->comm, "-solid_size", 3, s->size, 1e-6, 1e3, "m"));
  PetscCall(DrapeCheckReal(s->comm, "-solid_radius", 1, &s->radius, 1e-6, 1e3, "m"));
  PetscCall(DrapeCheckReal(s->comm, "-solid_height", 1, &s->height, 1e-6, 1e3, "m"));
  PetscCall(DrapeCheckInt(s->comm, "-solid_resolution", s->resolution, 3, 4096));
  if (s->has_plane) PetscCall(DrapeCheckReal(s->comm, "-solid_plane", 4, s->plane, -1e4, 1e4, "(normal components and offset, m)"));
  if (floorset) PetscCall(DrapeCheckReal(s->comm, "-solid_floor", 1, &floor_z, -1e4, 1e4, "m"));
  PetscCheck(!(floorset && s->has_plane), s->comm, PETSC_ERR_USER_INPUT, "Give either -solid_plane or -solid_floor, not both");
  if (floorset) {
    s->has_plane = PETSC_TRUE;
    s->plane[0]  = 0;
    s->plane[1]  = 0;
    s->plane[2]  = 1;
    s->plane[3]  = floor_z;
  }
  if (s->has_plane) {
    PetscReal nn = PetscSqrtReal(s->plane[0] * s->plane[0] + s->plane[1] * s->plane[1] + s->plane[2] * s->plane[2]);
    PetscCheck(nn > 0, s->comm, PETSC_ERR_USER_INPUT, "-solid_plane normal must not be zero");
    for (PetscInt i = 0; i < 4; i++) s->plane[i] /= nn;
    PetscCheck(PetscAbsReal(s->plane[3]) <= 1e4, s->comm, PETSC_ERR_USER_INPUT, "-solid_plane puts the plane %g m from the origin (its offset over the normal's length); at most 1e4 m", (double) s->plane[3]);
  }
  PetscFunctionReturn(0);
}

/* R = Rz Ry Rx: the body's rotation; A = scale R */
static void SolidRotation(const Solid s, PetscReal R[9])
{
  const PetscReal d  = PETSC_PI / 180;
  PetscReal       cx = PetscCosReal(s->rotate[0] * d), sx = PetscSinReal(s->rotate[0] * d);
  PetscReal       cy = PetscCosReal(s->rotate[1] * d), sy = PetscSinReal(s->rotate[1] * d);
  PetscReal       cz = PetscCosReal(s->rotate[2] * d), sz = PetscSinReal(s->rotate[2] * d);
  PetscReal       Rx[9] = {1, 0, 0, 0, cx, -sx, 0, sx, cx}, Ry[9] = {cy, 0, sy, 0, 1, 0, -sy, 0, cy}, Rz[9] = {cz, -sz, 0, sz, cz, 0, 0, 0, 1}, T[9];

  for (PetscInt i = 0; i < 3; i++)
    for (PetscInt j = 0; j < 3; j++) T[3 * i + j] = Ry[3 * i] * Rx[j] + Ry[3 * i + 1] * Rx[3 + j] + Ry[3 * i + 2] * Rx[6 + j];
  for (PetscInt i = 0; i < 3; i++)
    for (PetscInt j = 0; j < 3; j++) R[3 * i + j] = Rz[3 * i] * T[j] + Rz[3 * i + 1] * T[3 + j] + Rz[3 * i + 2] * T[6 + j];
}

static void SolidTransform(const Solid s, PetscReal A[9])
{
  SolidRotation(s, A);
  for (PetscInt i = 0; i < 9; i++) A[i] *= s->scale;
}

/* Signed distance (negative inside) and outward unit normal of the primitive in its
 * own frame (centred at the origin, cylinder along z), at body point q. */
static void PrimitiveDistance(const Solid s, const PetscReal q[3], PetscReal *dist, PetscReal n[3])
{
  n[0] = n[1] = 0;
  n[2]        = 1;
  if (s->type == SOLID_SPHERE) {
    const PetscReal l = PetscSqrtReal(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
    *dist             = l - s->radius;
    if (l > 0)
      for (PetscInt d = 0; d < 3; d++) n[d] = q[d] / l;
  } else if (s->type == SOLID_BOX) {
    PetscReal e[3], out = 0, in = -PETSC_MAX_REAL;
    PetscInt  axis = 0;
    for (PetscInt d = 0; d < 3; d++) {
      e[d] = PetscAbsReal(q[d]) - 0.5 * s->size[d];
      out += PetscSqr(PetscMax(e[d], 0));
      if (e[d] > in) in = e[d], axis = d;
    }
    if (in > 0) { /* outside: to the nearest point of the box */
      out   = PetscSqrtReal(out);
      *dist = out;
      for (PetscInt d = 0; d < 3; d++) n[d] = (q[d] < 0 ? -1 : 1) * PetscMax(e[d], 0) / out;
    } else { /* inside: to the nearest face */
      *dist   = in;
      n[2]    = 0;
      n[axis] = q[axis] < 0 ? -1 : 1;
    }
  } else { /* capped cylinder along z */
    const PetscReal rho = PetscSqrtReal(q[0] * q[0] + q[1] * q[1]), er = rho - s->radius, ez = PetscAbsReal(q[2]) - 0.5 * s->height;
    const PetscReal ur[2] = {rho > 0 ? q[0] / rho : 1, rho > 0 ? q[1] / rho : 0}, sz = q[2] < 0 ? -1 : 1;
    if (er > 0 || ez > 0) {
      const PetscReal a = PetscMax(er, 0), b = PetscMax(ez, 0), l = PetscSqrtReal(a * a + b * b);
      *dist = l;
      n[0]  = a * ur[0] / l;
      n[1]  = a * ur[1] / l;
      n[2]  = b * sz / l;
    } else if (er > ez) {
      *dist = er;
      n[0]  = ur[0];
      n[1]  = ur[1];
      n[2]  = 0;
    } else {
      *dist = ez;
      n[2]  = sz;
    }
  }
}

/* Generated primitives, centred at the origin, outward-oriented triangles. */
static PetscErrorCode SolidGenerate(Solid s, PetscInt *nv, PetscReal **v, PetscInt *nt, PetscInt **t)
{
  PetscInt m = s->resolution, k = 0, f = 0;

  PetscFunctionBeginUser;
  if (s->type == SOLID_BOX) {
    const PetscInt tri[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
    *nv                    = 8;
    *nt                    = 12;
    PetscCall(PetscMalloc2(24, v, 36, t));
    for (PetscInt i = 0; i < 8; i++) {
      (*v)[3 * i]     = 0.5 * s->size[0] * ((i == 1 || i == 2 || i == 5 || i == 6) ? 1 : -1);
      (*v)[3 * i + 1] = 0.5 * s->size[1] * ((i == 2 || i == 3 || i == 6 || i == 7) ? 1 : -1);
      (*v)[3 * i + 2] = 0.5 * s->size[2] * (i >= 4 ? 1 : -1);
    }
    for (PetscInt i = 0; i < 36; i++) (*t)[i] = tri[i];
  } else if (s->type == SOLID_SPHERE) {
    PetscInt rings = m / 2 < 2 ? 2 : m / 2;
    *nv            = 2 + (rings - 1) * m;
    *nt            = 2 * m * (rings - 1);
    PetscCall(PetscMalloc2(3 * *nv, v, 3 * *nt, t));
    (*v)[k++] = 0;
    (*v)[k++] = 0;
    (*v)[k++] = s->radius;
    for (PetscInt r = 1; r < rings; r++) {
      PetscReal th = PETSC_PI * r / rings;
      for (PetscInt j = 0; j < m; j++) {
        PetscReal ph = 2 * PETSC_PI * j / m;
        (*v)[k++]    = s->radius * PetscSinReal(th) * PetscCosReal(ph);
        (*v)[k++]    = s->radius * PetscSinReal(th) * PetscSinReal(ph);
        (*v)[k++]    = s->radius * PetscCosReal(th);
      }
    }
    (*v)[k++] = 0;
    (*v)[k++] = 0;
    (*v)[k++] = -s->radius;
#define RING(r, j) (1 + ((r) -1) * m + ((j) % m))
    for (PetscInt j = 0; j < m; j++) {
      PetscInt *q = *t + 3 * f++;
      q[0] = 0, q[1] = RING(1, j), q[2] = RING(1, j + 1);
    }
    for (PetscInt r = 1; r < rings - 1; r++) {
      for (PetscInt j = 0; j < m; j++) {
        PetscInt *q = *t + 3 * f++;
        q[0] = RING(r, j), q[1] = RING(r + 1, j), q[2] = RING(r + 1, j + 1);
        q    = *t + 3 * f++;
        q[0] = RING(r, j), q[1] = RING(r + 1, j + 1), q[2] = RING(r, j + 1);
      }
    }
    for (PetscInt j = 0; j < m; j++) {
      PetscInt *q = *t + 3 * f++;
      q[0] = *nv - 1, q[1] = RING(rings - 1, j + 1), q[2] = RING(rings - 1, j);
    }
#undef RING
  } else { /* cylinder along z */
    *nv = 2 + 2 * m;
    *nt = 4 * m;
    PetscCall(PetscMalloc2(3 * *nv, v, 3 * *nt, t));
    for (PetscInt side = 0; side < 2; side++) {
      PetscReal z = (side ? 0.5 : -0.5) * s->height;
      (*v)[k++]   = 0;
      (*v)[k++]   = 0;
      (*v)[k++]   = z;
      for (PetscInt j = 0; j < m; j++) {
        (*v)[k++] = s->radius * PetscCosReal(2 * PETSC_PI * j / m);
        (*v)[k++] = s->radius * PetscSinReal(2 * PETSC_PI * j / m);
        (*v)[k++] = z;
      }
    }
    for (PetscInt j = 0; j < m; j++) {
      PetscInt  b0 = 1 + j, b1 = 1 + (j + 1) % m, t0 = m + 2 + j, t1 = m + 2 + (j + 1) % m;
      PetscInt *q = *t + 3 * f++;
      q[0] = 0, q[1] = b1, q[2] = b0;
      q    = *t + 3 * f++;
      q[0] = m + 1, q[1] = t0, q[2] = t1;
      q    = *t + 3 * f++;
      q[0] = b0, q[1] = b1, q[2] = t1;
      q    = *t + 3 * f++;
      q[0] = b0, q[1] = t1, q[2] = t0;
    }
  }
  PetscFunctionReturn(0);
}

typedef struct {
  Solid     s;
  PetscReal A[9];
} SolidRead;

static PetscErrorCode SolidReadFile(void *ctx)
{
  SolidRead *r = (SolidRead *) ctx;

  PetscFunctionBeginUser;
  PetscCall(SolidMeshCreateFromFile(r->s->file, r->A, r->s->translate, &r->s->mesh));
  PetscFunctionReturn(0);
}

PetscErrorCode SolidSetUp(Solid s)
{
  PetscReal A[9];

  PetscFunctionBeginUser;
  if (s->type == SOLID_NONE) PetscFunctionReturn(0);
  SolidTransform(s, A);
  if (s->type == SOLID_MESH) {
    /* every rank reads the same file (the tree is replicated) and fails alike: one message */
    SolidRead r = {.s = s};
    PetscCall(PetscArraycpy(r.A, A, 9));
    PetscCall(DrapeCollective(s->comm, SolidReadFile, &r));
    PetscCall(SolidMeshGetBoundingBox(s->mesh, s->lo, s->hi));
  } else {
    /* a primitive: exact distances (PrimitiveDistance); its triangles for pictures,
     * and its box from the corners of its own box (the sphere's: exact) */
    PetscInt   nv, nt;
    PetscReal *v, half[3];
    PetscInt  *t;
    SolidRotation(s, s->R);
    PetscCall(SolidGenerate(s, &nv, &v, &nt, &t));
    for (PetscInt i = 0; i < nv; i++) {
      PetscReal p[3] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
      for (PetscInt d = 0; d < 3; d++) v[3 * i + d] = A[3 * d] * p[0] + A[3 * d + 1] * p[1] + A[3 * d + 2] * p[2] + s->translate[d];
    }
    s->ntri = nt;
    PetscCall(PetscMalloc1(9 * nt, &s->tri));
    for (PetscInt f = 0; f < nt; f++)
      for (PetscInt c = 0; c < 3; c++)
        for (PetscInt d = 0; d < 3; d++) s->tri[9 * f + 3 * c + d] = v[3 * t[3 * f + c] + d];
    PetscCall(PetscFree2(v, t));
    if (s->type == SOLID_BOX)
      for (PetscInt d = 0; d < 3; d++) half[d] = 0.5 * s->size[d];
    else {
      half[0] = half[1] = s->radius;
      half[2]           = s->type == SOLID_SPHERE ? s->radius : 0.5 * s->height;
    }
    for (PetscInt d = 0; d < 3; d++) {
      s->lo[d] = PETSC_MAX_REAL;
      s->hi[d] = -PETSC_MAX_REAL;
    }
    for (PetscInt c = 0; c < 8; c++) {
      const PetscReal q[3] = {(c & 1 ? 1 : -1) * half[0], (c & 2 ? 1 : -1) * half[1], (c & 4 ? 1 : -1) * half[2]};
      for (PetscInt d = 0; d < 3; d++) {
        const PetscReal x = s->type == SOLID_SPHERE ? s->translate[d] + q[d] * s->scale : s->translate[d] + A[3 * d] * q[0] + A[3 * d + 1] * q[1] + A[3 * d + 2] * q[2];
        s->lo[d]          = PetscMin(s->lo[d], x);
        s->hi[d]          = PetscMax(s->hi[d], x);
      }
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SolidView(Solid s, PetscViewer viewer)
{
  PetscFunctionBeginUser;
  if (s->mesh) {
    PetscInt nv, nt;
    PetscCall(SolidMeshGetSize(s->mesh, &nv, &nt));
    PetscCall(PetscViewerASCIIPrintf(viewer, "Solid: mesh %s, %" PetscInt_FMT " triangles in an AABB tree, box [%g,%g]x[%g,%g]x[%g,%g] m\n", s->file, nt, (double) s->lo[0], (double) s->hi[0], (double) s->lo[1], (double) s->hi[1], (double) s->lo[2],
                                     (double) s->hi[2]));
  } else if (s->type != SOLID_NONE)
    PetscCall(PetscViewerASCIIPrintf(viewer, "Solid: %s (exact distance), box [%g,%g]x[%g,%g]x[%g,%g] m\n", solid_type_names[s->type], (double) s->lo[0], (double) s->hi[0], (double) s->lo[1], (double) s->hi[1], (double) s->lo[2], (double) s->hi[2]));
  if (s->has_plane) PetscCall(PetscViewerASCIIPrintf(viewer, "Solid: plane %g x + %g y + %g z = %g (solid below)\n", (double) s->plane[0], (double) s->plane[1], (double) s->plane[2], (double) s->plane[3]));
  PetscFunctionReturn(0);
}

PetscErrorCode SolidDestroy(Solid *solid)
{
  PetscFunctionBeginUser;
  if (!*solid) PetscFunctionReturn(0);
  if ((*solid)->mesh) PetscCall(SolidMeshDestroy(&(*solid)->mesh));
  PetscCall(PetscFree((*solid)->tri));
  PetscCall(PetscFree(*solid));
  PetscFunctionReturn(0);
}

PetscErrorCode SolidIsEmpty(Solid s, PetscBool *empty)
{
  PetscFunctionBeginUser;
  *empty = (PetscBool) (s->type == SOLID_NONE && !s->has_plane);
  PetscFunctionReturn(0);
}

PetscBool SolidBoxNear(Solid s, const PetscReal lo[3], const PetscReal hi[3], PetscReal grow)
{
  if (s->type != SOLID_NONE) {
    PetscBool apart = PETSC_FALSE;
    for (PetscInt d = 0; d < 3; d++) apart = (PetscBool) (apart || lo[d] > s->hi[d] + grow || hi[d] < s->lo[d] - grow);
    if (!apart) return PETSC_TRUE;
  }
  if (s->has_plane) {
    /* lowest corner of the box along n */
    PetscReal m = 0;
    for (PetscInt d = 0; d < 3; d++) m += s->plane[d] * (s->plane[d] > 0 ? lo[d] : hi[d]);
    if (m <= s->plane[3] + grow) return PETSC_TRUE;
  }
  return PETSC_FALSE;
}

/* The primitive alone at world point p: signed distance and outward normal (world). */
static inline void PrimitiveQuery(const Solid s, const PetscReal p[3], PetscReal *dist, PetscReal normal[3])
{
  PetscReal q[3], r[3], dl, nl[3];

  for (PetscInt d = 0; d < 3; d++) r[d] = (p[d] - s->translate[d]) / s->scale;
  for (PetscInt d = 0; d < 3; d++) q[d] = s->R[d] * r[0] + s->R[3 + d] * r[1] + s->R[6 + d] * r[2]; /* R^T r */
  PrimitiveDistance(s, q, &dl, nl);
  *dist = s->scale * dl;
  for (PetscInt d = 0; d < 3; d++) normal[d] = s->R[3 * d] * nl[0] + s->R[3 * d + 1] * nl[1] + s->R[3 * d + 2] * nl[2];
}

/* The first point of the segment p0 -> p1 in the (convex) primitive, from outside:
 * its signed distance f(t) along the segment is convex, so a golden-section search
 * finds its minimum and a bisection the first root before it. */
static void PrimitiveSweep(const Solid s, const PetscReal p0[3], const PetscReal p1[3], PetscReal *t, PetscReal normal[3], PetscBool *hit)
{
  const PetscReal L = PetscSqrtReal(PetscSqr(p1[0] - p0[0]) + PetscSqr(p1[1] - p0[1]) + PetscSqr(p1[2] - p0[2])), g = 0.5 * (PetscSqrtReal(5) - 1);
  PetscReal       f0, f1, n[3], a = 0, b = 1;

#define AT(tt, f)                                                                                                                                                                                                                                        \
  do {                                                                                                                                                                                                                                                   \
    const PetscReal u_ = (tt), p_[3] = {p0[0] + u_ * (p1[0] - p0[0]), p0[1] + u_ * (p1[1] - p0[1]), p0[2] + u_ * (p1[2] - p0[2])};                                                                                                                       \
    PrimitiveQuery(s, p_, &(f), n);                                                                                                                                                                                                                      \
  } while (0)
  *hit = PETSC_FALSE;
  AT(0, f0);
  AT(1, f1);
  if (f0 <= 0 || f0 + f1 > L) return; /* starts inside (no crossing), or too short to reach it (f is 1-Lipschitz in t L) */
  if (f1 >= 0) {                      /* both ends outside: through it? */
    PetscReal x1 = 1 - g, x2 = g, fx1, fx2;
    AT(x1, fx1);
    AT(x2, fx2);
    for (PetscInt it = 0; it < 60 && fx1 >= 0 && fx2 >= 0; it++) {
      if (fx1 < fx2) {
        b   = x2;
        x2  = x1;
        fx2 = fx1;
        x1  = b - g * (b - a);
        AT(x1, fx1);
      } else {
        a   = x1;
        x1  = x2;
        fx1 = fx2;
        x2  = a + g * (b - a);
        AT(x2, fx2);
      }
    }
    if (fx1 >= 0 && fx2 >= 0) return;
    b = fx1 < 0 ? x1 : x2;
    a = 0;
  }
  for (PetscInt it = 0; it < 60; it++) { /* f(a) > 0 >= f(b) */
    const PetscReal m = 0.5 * (a + b);
    PetscReal       fm;
    AT(m, fm);
    if (fm > 0)
      a = m;
    else
      b = m;
  }
#undef AT
  {
    const PetscReal p[3] = {p0[0] + a * (p1[0] - p0[0]), p0[1] + a * (p1[1] - p0[1]), p0[2] + a * (p1[2] - p0[2])};
    PetscReal       f;
    PrimitiveQuery(s, p, &f, normal);
  }
  *t   = a;
  *hit = PETSC_TRUE;
}

PetscErrorCode SolidSweep(Solid s, const PetscReal p0[3], const PetscReal p1[3], PetscBool mesh_only, PetscReal *t, PetscReal normal[3], PetscBool *hit)
{
  PetscReal lo[3], hi[3], tb, nb[3];
  PetscBool apart = PETSC_FALSE, hb;

  PetscFunctionBeginUser;
  *hit = PETSC_FALSE;
  *t   = 1;
  if (mesh_only && !s->mesh) PetscFunctionReturn(0);
  for (PetscInt d = 0; d < 3; d++) {
    lo[d] = PetscMin(p0[d], p1[d]);
    hi[d] = PetscMax(p0[d], p1[d]);
    apart = (PetscBool) (apart || lo[d] > s->hi[d] || hi[d] < s->lo[d]);
  }
  if (s->has_plane && !mesh_only) {
    const PetscReal d0 = s->plane[0] * p0[0] + s->plane[1] * p0[1] + s->plane[2] * p0[2] - s->plane[3];
    const PetscReal d1 = s->plane[0] * p1[0] + s->plane[1] * p1[1] + s->plane[2] * p1[2] - s->plane[3];
    if (d0 > 0 && d1 < 0) {
      *hit = PETSC_TRUE;
      *t   = d0 / (d0 - d1);
      for (PetscInt d = 0; d < 3; d++) normal[d] = s->plane[d];
    }
  }
  if (s->type == SOLID_NONE || apart) PetscFunctionReturn(0);
  hb = PETSC_FALSE;
  if (s->mesh)
    PetscCall(SolidMeshSweep(s->mesh, p0, p1, &tb, nb, &hb));
  else if (!mesh_only)
    PrimitiveSweep(s, p0, p1, &tb, nb, &hb);
  if (hb && (!*hit || tb < *t)) {
    *hit = PETSC_TRUE;
    *t   = tb;
    for (PetscInt d = 0; d < 3; d++) normal[d] = nb[d];
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SolidQuery(Solid s, const PetscReal p[3], PetscReal *distance, PetscReal normal[3])
{
  PetscFunctionBeginUser;
  *distance = PETSC_MAX_REAL;
  if (s->has_plane) {
    *distance = s->plane[0] * p[0] + s->plane[1] * p[1] + s->plane[2] * p[2] - s->plane[3];
    for (PetscInt d = 0; d < 3; d++) normal[d] = s->plane[d];
  }
  if (s->type != SOLID_NONE && s->type != SOLID_MESH) {
    PetscReal dl, nl[3];
    PrimitiveQuery(s, p, &dl, nl);
    if (dl < *distance) {
      *distance = dl;
      for (PetscInt d = 0; d < 3; d++) normal[d] = nl[d];
    }
  }
  if (s->mesh) {
    PetscReal c[3], e[3], l;
    PetscBool inside;
    PetscCall(SolidMeshQuery(s->mesh, p, c, &inside));
    for (PetscInt d = 0; d < 3; d++) e[d] = p[d] - c[d];
    l = PetscSqrtReal(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    if ((inside ? -l : l) < *distance) {
      *distance = inside ? -l : l;
      if (l > 0)
        for (PetscInt d = 0; d < 3; d++) normal[d] = (inside ? -e[d] : e[d]) / l;
      else {
        /* on the surface: point away from the box centre */
        PetscReal g[3], n = 0;
        for (PetscInt d = 0; d < 3; d++) {
          g[d] = p[d] - 0.5 * (s->lo[d] + s->hi[d]);
          n += g[d] * g[d];
        }
        for (PetscInt d = 0; d < 3; d++) normal[d] = g[d] / PetscMax(PetscSqrtReal(n), PETSC_SMALL);
      }
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SolidGetTriangles(Solid s, PetscInt *ntri, PetscReal **xyz)
{
  PetscFunctionBeginUser;
  *ntri = 0;
  *xyz  = NULL;
  if (s->tri) {
    *ntri = s->ntri;
    PetscCall(PetscMalloc1(9 * s->ntri, xyz));
    PetscCall(PetscArraycpy(*xyz, s->tri, 9 * s->ntri));
  }
  if (!s->mesh) PetscFunctionReturn(0);
  PetscCall(SolidMeshGetSize(s->mesh, NULL, ntri));
  PetscCall(PetscMalloc1(9 * *ntri, xyz));
  PetscCall(SolidMeshGetTriangles(s->mesh, *xyz));
  PetscFunctionReturn(0);
}
