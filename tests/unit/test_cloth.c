static const char help[] = "Cloth-level checks: rigid motions feel no internal force; internal forces\n"
                           "rotate with the cloth and have zero resultant and zero torque; a sheet rolled\n"
                           "into a cylinder stores the bending energy of its strip rigidity.\n";

#include <cloth.h>
#include <drape.h>

/* A random rotation (unit quaternion) and translation. */
static PetscErrorCode RandomRigidMotion(PetscRandom rnd, PetscReal R[9], PetscReal t[3])
{
  PetscReal q[4], n = 0;

  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < 4; i++) {
    PetscCall(PetscRandomGetValueReal(rnd, &q[i]));
    q[i] -= 0.5;
    n += q[i] * q[i];
  }
  for (PetscInt i = 0; i < 4; i++) q[i] /= PetscSqrtReal(n);
  R[0] = 1 - 2 * (q[2] * q[2] + q[3] * q[3]);
  R[1] = 2 * (q[1] * q[2] - q[0] * q[3]);
  R[2] = 2 * (q[1] * q[3] + q[0] * q[2]);
  R[3] = 2 * (q[1] * q[2] + q[0] * q[3]);
  R[4] = 1 - 2 * (q[1] * q[1] + q[3] * q[3]);
  R[5] = 2 * (q[2] * q[3] - q[0] * q[1]);
  R[6] = 2 * (q[1] * q[3] - q[0] * q[2]);
  R[7] = 2 * (q[2] * q[3] + q[0] * q[1]);
  R[8] = 1 - 2 * (q[1] * q[1] + q[2] * q[2]);
  for (PetscInt i = 0; i < 3; i++) {
    PetscCall(PetscRandomGetValueReal(rnd, &t[i]));
    t[i] = 4 * (t[i] - 0.5);
  }
  PetscFunctionReturn(0);
}

static void Apply(const PetscReal R[9], const PetscReal t[3], PetscInt n, const PetscScalar *x, PetscScalar *y)
{
  for (PetscInt k = 0; k < n; k++)
    for (PetscInt i = 0; i < 3; i++) y[3 * k + i] = R[3 * i] * x[3 * k] + R[3 * i + 1] * x[3 * k + 1] + R[3 * i + 2] * x[3 * k + 2] + (t ? t[i] : 0);
}

static PetscErrorCode MaxAbs(MPI_Comm comm, PetscInt n, const PetscScalar *a, PetscReal *m)
{
  PetscReal loc = 0;

  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < n; i++) loc = PetscMax(loc, PetscAbsReal(a[i]));
  PetscCall(MPIU_Allreduce(&loc, m, 1, MPIU_REAL, MPI_MAX, comm));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  MPI_Comm      comm;
  Cloth         cloth;
  ClothInfo     info;
  ClothEnergies en;
  PetscRandom   rnd;
  PetscScalar  *x, *v, *y, *f, *g, *Rf;
  PetscReal     R[9], t[3], fscale, m, loc[6], sum[6];
  PetscInt      n, passed = 0;

  PetscCall(PetscInitialize(&argc, &argv, NULL, help));
  comm = PETSC_COMM_WORLD;
  PetscCall(DrapeInitialize());
  PetscCall(ClothCreate(comm, &cloth));
  PetscCall(ClothSetFromOptions(cloth));
  PetscCall(ClothSetUp(cloth));
  PetscCall(ClothGetInfo(cloth, &info));
  n = 3 * info.nowned;
  PetscCall(PetscMalloc6(n, &x, n, &v, n, &y, n, &f, n, &g, n, &Rf));
  PetscCall(PetscRandomCreate(comm, &rnd));
  PetscCall(PetscRandomSetSeed(rnd, 7));
  PetscCall(PetscRandomSeed(rnd));
  fscale = PetscMax(info.stretch[0], info.stretch[1]) * info.spacing[0];

  /* 1. the flat sheet at rest, moved rigidly: no internal force, no internal energy */
  PetscCall(ClothSetInitialState(cloth, x, v));
  PetscCall(RandomRigidMotion(rnd, R, t));
  Apply(R, t, info.nowned, x, y);
  PetscCall(ClothComputeInternalForce(cloth, y, f));
  PetscCall(MaxAbs(comm, n, f, &m));
  PetscCall(ClothComputeEnergies(cloth, y, v, &en));
  PetscCall(PetscPrintf(comm, "rigid motion of the rest state: max |F_int| = %.3e (scale %.3e), internal energy %.3e J\n", (double) m, (double) fscale, (double) (en.stretch + en.shear + en.bend)));
  PetscCheck(m < 1e-9 * fscale && en.stretch + en.shear + en.bend < 1e-12 * fscale * info.size[0], comm, PETSC_ERR_PLIB, "a rigidly moved cloth feels internal forces");
  passed++;

  /* 2. a random deformation: forces rotate with the cloth, sum to zero, no torque */
  for (PetscInt i = 0; i < n; i++) {
    PetscReal r;
    PetscCall(PetscRandomGetValueReal(rnd, &r));
    x[i] += 0.2 * info.spacing[0] * (r - 0.5);
  }
  PetscCall(ClothComputeInternalForce(cloth, x, f));
  Apply(R, t, info.nowned, x, y);
  PetscCall(ClothComputeInternalForce(cloth, y, g));
  Apply(R, NULL, info.nowned, f, Rf);
  for (PetscInt i = 0; i < n; i++) Rf[i] -= g[i];
  PetscCall(MaxAbs(comm, n, Rf, &m));
  PetscCall(MaxAbs(comm, n, f, &fscale));
  PetscCall(PetscPrintf(comm, "deformed cloth: max |R F(x) - F(Rx + t)| = %.3e (max |F| %.3e)\n", (double) m, (double) fscale));
  PetscCheck(m < 1e-11 * fscale, comm, PETSC_ERR_PLIB, "internal forces do not rotate with the cloth");
  passed++;
  for (PetscInt i = 0; i < 6; i++) loc[i] = 0;
  for (PetscInt k = 0; k < info.nowned; k++) {
    const PetscScalar *p = x + 3 * k, *q = f + 3 * k;
    for (PetscInt i = 0; i < 3; i++) loc[i] += q[i];
    loc[3] += p[1] * q[2] - p[2] * q[1];
    loc[4] += p[2] * q[0] - p[0] * q[2];
    loc[5] += p[0] * q[1] - p[1] * q[0];
  }
  PetscCall(MPIU_Allreduce(loc, sum, 6, MPIU_REAL, MPI_SUM, comm));
  m = 0;
  for (PetscInt i = 0; i < 6; i++) m = PetscMax(m, PetscAbsReal(sum[i]));
  PetscCall(PetscPrintf(comm, "deformed cloth: |resultant|, |torque| <= %.3e (max |F| %.3e)\n", (double) m, (double) fscale));
  PetscCheck(m < 1e-10 * fscale * info.nparticles, comm, PETSC_ERR_PLIB, "internal forces have a resultant or a torque");
  passed++;

  /* 3. developable bending: a 61 x 61 sheet (Bw, Bf, Bb = 2e-5, 1e-5, 1.2e-5 N m) rolled
   * isometrically into a cylinder of curvature k whose generators are normal to the
   * direction n at 0, 90 and 45 degrees to the warp stores B(n) k^2/2 per area: Bw, Bf,
   * Bb (drape's model; the paper's: Bw, Bf, (Bw + Bf)/4). In drape's model the triple
   * next to a line's free end stands for the end's share too, so the square and a
   * circle cut from it store their area's energy to 1e-3 (measured up to 4e-4 and
   * 3e-5; without the ends' shares 1.9-2.5 % and 1.8-2.3 % low); the paper's model
   * keeps the particle's share (1.7 % low here). */
  {
    const char     *models[3] = {"drape", "paper", "drape"}, *shapes[3] = {"square", "square", "circle"};
    const PetscReal bw = 2e-5, bf = 1e-5, bb = 1.2e-5, k = 1.0;
    for (PetscInt mo = 0; mo < 3; mo++) {
      Cloth        roll;
      ClothInfo    ri;
      PetscScalar *xr, *vr;
      PetscReal    c[2] = {0, 0}, csum[2];
      PetscCall(PetscOptionsSetValue(NULL, "-da_grid_x", "61"));
      PetscCall(PetscOptionsSetValue(NULL, "-da_grid_y", "61"));
      PetscCall(PetscOptionsSetValue(NULL, "-cloth_bend", mo == 1 ? "2e-5,1e-5" : "2e-5,1e-5,1.2e-5"));
      PetscCall(PetscOptionsSetValue(NULL, "-cloth_shape", shapes[mo]));
      PetscCall(PetscOptionsSetValue(NULL, "-cloth_model", models[mo]));
      PetscCall(PetscOptionsSetValue(NULL, "-cloth_pin", "none")); /* the energy does not see pins, and the circle cuts away the corners the command line pins */
      PetscCall(ClothCreate(comm, &roll));
      PetscCall(ClothSetFromOptions(roll));
      PetscCall(ClothSetUp(roll));
      PetscCall(ClothGetInfo(roll, &ri));
      PetscCall(PetscMalloc2(3 * ri.nowned + 1, &xr, 3 * ri.nowned + 1, &vr));
      for (PetscInt a = 0; a < 3; a++) {
        const PetscReal angle = a == 2 ? PETSC_PI / 4 : a * PETSC_PI / 2, nv[2] = {PetscCosReal(angle), PetscSinReal(angle)}, tv[2] = {-nv[1], nv[0]};
        const PetscReal expect = a == 0 ? bw : a == 1 ? bf : (mo == 1 ? 0.25 * (bw + bf) : bb);
        PetscReal       e;
        PetscCall(ClothSetInitialState(roll, xr, vr));
        for (PetscInt q = 0; q < ri.nowned; q++) c[0] += xr[3 * q], c[1] += xr[3 * q + 1];
        PetscCall(MPIU_Allreduce(c, csum, 2, MPIU_REAL, MPI_SUM, comm));
        for (PetscInt q = 0; q < ri.nowned; q++) {
          const PetscReal px = xr[3 * q] - csum[0] / ri.nparticles, py = xr[3 * q + 1] - csum[1] / ri.nparticles, u = px * nv[0] + py * nv[1], w = px * tv[0] + py * tv[1];
          xr[3 * q]     = csum[0] / ri.nparticles + w * tv[0] + PetscSinReal(k * u) / k * nv[0];
          xr[3 * q + 1] = csum[1] / ri.nparticles + w * tv[1] + PetscSinReal(k * u) / k * nv[1];
          xr[3 * q + 2] += (1 - PetscCosReal(k * u)) / k;
        }
        c[0] = c[1] = 0;
        PetscCall(ClothComputeEnergies(roll, xr, vr, &en));
        e = en.bend / (0.5 * k * k * ri.mass / ri.density);
        PetscCall(PetscPrintf(comm, "%s model, %s rolled at %g deg: bending rigidity %.4e N m from the energy, %.4e expected\n", models[mo], shapes[mo], (double) (angle * 180 / PETSC_PI), (double) e, (double) expect));
        PetscCheck(PetscAbsReal(e / expect - 1) < (mo == 1 ? 0.03 : 1e-3), comm, PETSC_ERR_PLIB, "the rolled sheet's bending energy is not its strip rigidity");
        passed++;
      }
      PetscCall(PetscFree2(xr, vr));
      PetscCall(ClothDestroy(&roll));
    }
  }

  /* 4. bending that varies with curvature (-cloth_bend_table): the paper's model (thread
   * triples only) of denim rolled to k = 25 1/m across the warp, then the weft, stores
   * 2 Phi(k_t) / k_t^2 times the energy of the same roll at the table's first sample,
   * Phi(k) = int_0^k b(t) t dt by Simpson's rule on the table (ARCSim's denim: curvature
   * along the warp from its v-hinge row, along the weft from its u-hinge row) and k_t =
   * 2 sin(k L / 2) / L the triples' curvature. Fails if a row, the rest length or the
   * sample spacing were mapped wrongly. */
  {
    const PetscReal k = 25, bw[5] = {96.951576, 107.848228, 113.060738, 120.569740, 79.781021}, bf[5] = {64.196457, 60.286175, 60.943428, 62.433697, 19.824701};
    for (PetscInt a = 0; a < 2; a++) {
      PetscReal E[2];
      for (PetscInt tab = 0; tab < 2; tab++) {
        Cloth        roll;
        ClothInfo    ri;
        PetscScalar *xr, *vr;
        PetscCall(PetscOptionsSetValue(NULL, "-da_grid_x", "61"));
        PetscCall(PetscOptionsSetValue(NULL, "-da_grid_y", "61"));
        PetscCall(PetscOptionsClearValue(NULL, "-cloth_bend"));
        PetscCall(PetscOptionsSetValue(NULL, "-cloth_shape", "square"));
        PetscCall(PetscOptionsSetValue(NULL, "-cloth_model", "paper"));
        PetscCall(PetscOptionsSetValue(NULL, "-cloth_fabric", "denim"));
        PetscCall(PetscOptionsSetValue(NULL, "-cloth_bend_table", tab ? "1" : "0"));
        PetscCall(ClothCreate(comm, &roll));
        PetscCall(ClothSetFromOptions(roll));
        PetscCall(ClothSetUp(roll));
        PetscCall(ClothGetInfo(roll, &ri));
        PetscCall(PetscMalloc2(3 * ri.nowned + 1, &xr, 3 * ri.nowned + 1, &vr));
        PetscCall(ClothSetInitialState(roll, xr, vr));
        for (PetscInt q = 0; q < ri.nowned; q++) { /* the sheet is centred on the origin */
          const PetscReal u = xr[3 * q + a];
          xr[3 * q + a]     = PetscSinReal(k * u) / k;
          xr[3 * q + 2] += (1 - PetscCosReal(k * u)) / k;
        }
        PetscCall(ClothComputeEnergies(roll, xr, vr, &en));
        E[tab] = en.bend;
        PetscCall(PetscFree2(xr, vr));
        PetscCall(ClothDestroy(&roll));
      }
      {
        const PetscReal *b = a == 0 ? bw : bf, L = 1.0 / 60, kt = 2 * PetscSinReal(k * L / 2) / L;
        const PetscInt   ns  = 1000;
        PetscReal        phi = 0, expect;
        for (PetscInt i = 0; i <= ns; i++) { /* Simpson on [0, kt]: b(t) t is smooth there (kt < 30) */
          const PetscReal t = kt * i / ns, bt = (t < 10 ? b[0] + (b[1] - b[0]) * t / 10 : t < 20 ? b[1] + (b[2] - b[1]) * (t - 10) / 10 : b[2] + (b[3] - b[2]) * (t - 20) / 10) / b[0];
          phi += (i == 0 || i == ns ? 1 : i % 2 ? 4 : 2) * bt * t;
        }
        phi *= kt / ns / 3;
        expect = 2 * phi / (kt * kt);
        PetscCall(PetscPrintf(comm, "paper model, denim rolled to %g 1/m along the %s with -cloth_bend_table: %.6f of the energy at the first sample, %.6f expected\n", (double) k, a == 0 ? "warp" : "weft", (double) (E[1] / E[0]), (double) expect));
        PetscCheck(PetscAbsReal(E[1] / E[0] / expect - 1) < 1e-6, comm, PETSC_ERR_PLIB, "the bending table's energy is not the integral of its moment");
        passed++;
      }
    }
    PetscCall(PetscOptionsClearValue(NULL, "-cloth_fabric"));
    PetscCall(PetscOptionsClearValue(NULL, "-cloth_bend_table"));
  }

  PetscCall(PetscPrintf(comm, "%" PetscInt_FMT " passed, 0 failed\n", passed));
  PetscCall(PetscRandomDestroy(&rnd));
  PetscCall(PetscFree6(x, v, y, f, g, Rf));
  PetscCall(ClothDestroy(&cloth));
  PetscCall(DrapeFinalize());
  PetscCall(PetscFinalize());
  return 0;
}
