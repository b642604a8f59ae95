// Broad phase of self-contact: CGAL's box intersection (Zomorodian & Edelsbrunner's
// streamed segment tree) over axis-aligned boxes of the cloth's vertices, triangles
// and edges, each spanning the primitive's start and end positions of the step
// grown by r. No exception crosses the extern "C" line.
#include <CGAL/box_intersection_d.h>

#include <algorithm>
#include <utility>
#include <vector>

#include "selfcontactimpl.h"

typedef CGAL::Box_intersection_d::Box_with_info_d<double, 3, PetscInt> Box;

template <int NV> static void MakeBoxes(PetscInt n, const PetscInt *prim, const PetscReal *x0, const PetscReal *x1, PetscReal r, std::vector<Box> &boxes)
{
  boxes.clear();
  boxes.reserve(n);
  for (PetscInt k = 0; k < n; k++) {
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (int v = 0; v < NV; v++) {
      const PetscInt p = prim[NV * k + v];
      for (int d = 0; d < 3; d++) {
        lo[d] = std::min(lo[d], std::min(x0[3 * p + d], x1[3 * p + d]));
        hi[d] = std::max(hi[d], std::max(x0[3 * p + d], x1[3 * p + d]));
      }
    }
    for (int d = 0; d < 3; d++) {
      lo[d] -= r;
      hi[d] += r;
    }
    boxes.push_back(Box(lo, hi, k));
  }
}

static PetscErrorCode Store(std::vector<std::pair<PetscInt, PetscInt>> &pairs, PetscInt *n, PetscInt **out)
{
  PetscFunctionBeginUser;
  std::sort(pairs.begin(), pairs.end()); /* the order of the sweeps is the same on every rank and run */
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  *n = (PetscInt) pairs.size();
  PetscCall(PetscMalloc1(2 * pairs.size() + 1, out));
  for (size_t k = 0; k < pairs.size(); k++) {
    (*out)[2 * k]     = pairs[k].first;
    (*out)[2 * k + 1] = pairs[k].second;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SelfBroadPhase(const SelfMesh *m, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscInt *npt, PetscInt **pt, PetscInt *nee, PetscInt **ee)
{
  PetscFunctionBeginUser;
  try {
    std::vector<Box>                           vb, tb, eb;
    std::vector<std::pair<PetscInt, PetscInt>> pairs;
    MakeBoxes<1>(m->nv, m->vert, x0, x1, r, vb);
    MakeBoxes<3>(m->nt, m->tri, x0, x1, r, tb);
    CGAL::box_intersection_d(vb.begin(), vb.end(), tb.begin(), tb.end(), [&](const Box &v, const Box &t) {
      const PetscInt p = m->vert[v.info()], *T = m->tri + 3 * t.info();
      if (p != T[0] && p != T[1] && p != T[2]) pairs.push_back(std::make_pair(v.info(), t.info()));
    });
    PetscCall(Store(pairs, npt, pt));
    pairs.clear();
    MakeBoxes<2>(m->ne, m->edge, x0, x1, r, eb);
    CGAL::box_self_intersection_d(eb.begin(), eb.end(), [&](const Box &a, const Box &b) {
      const PetscInt *A = m->edge + 2 * a.info(), *B = m->edge + 2 * b.info();
      if (A[0] != B[0] && A[0] != B[1] && A[1] != B[0] && A[1] != B[1]) pairs.push_back(std::make_pair(std::min(a.info(), b.info()), std::max(a.info(), b.info())));
    });
    PetscCall(Store(pairs, nee, ee));
  } catch (const std::bad_alloc &) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_MEM,
            "Out of memory in the self-contact broad phase (CGAL's box intersection of %" PetscInt_FMT " vertices, %" PetscInt_FMT " triangles and %" PetscInt_FMT
            " edges): this run needs more memory than the machine gives it; use -contact_self_broad_phase hash, a smaller lattice, or more memory",
            m->nv, m->nt, m->ne);
  } catch (const std::exception &e) {
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "CGAL's box intersection failed in the self-contact broad phase: %s", e.what());
  }
  PetscFunctionReturn(0);
}
