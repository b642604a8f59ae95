/* Named fabrics (-cloth_fabric): measured materials converted to the model's
 * continuum rigidities.
 *
 * Source: the measured database of H. Wang, R. Ramamoorthi and J. F. O'Brien,
 * "Data-Driven Elastic Models for Cloth: Modeling and Measurement", ACM Trans.
 * Graph. 30(4):71 (SIGGRAPH 2011), as distributed with the ARCSim simulator
 * (materials/<name>.json and materials/README, e.g. in the public ARCSim 0.2.1
 * sources). The numbers below are those files' zero-strain entries, copied
 * verbatim; use and fibre content are the README's.
 *
 * What the file entries mean (ARCSim's src/dde.cpp and src/physics.cpp):
 *   density        areal density, kg/m^2 (face mass = area x density).
 *   stretching[0]  [s_uu, s_uv, s_vv, s_sh] at zero strain (stretching[1..5] are
 *                  the large-strain samples, blended in only as the strain grows);
 *                  dde.cpp doubles them, k = 2 s (evaluate_stretching_sample:
 *                  "real_elastic[3]*=2;"). The time step integrates
 *                  physics.cpp's stretching_force, whose gradient is
 *                    k[0]*G(0,0)*fuu + k[2]*G(1,1)*fvv
 *                    + k[1]*(G(0,0)*fvv + G(1,1)*fuu) + 2*k[3]*G(0,1)*fuv
 *                  with fuu, fvv, fuv the gradients of G_uu, G_vv, G_uv (G the
 *                  Green strain): the gradient of the energy per area
 *                    W = (k_uu G_uu^2 + k_vv G_vv^2 + 2 k_uv G_uu G_vv) / 2 + k_sh G_uv^2
 *                  (ARCSim 0.2.1 states this W in a comment of that function).
 *                  The 1/2 on k_sh G_uv^2 is only in stretching_energy(), which
 *                  the time step does not call. At small strain G_uu = eps_u and
 *                  G_uv = gamma/2 (gamma the shear angle), so the tensile
 *                  rigidities are 2 s_uu and 2 s_vv (N/m) and the shear energy is
 *                  2 s_sh gamma^2 / 4 = s_sh gamma^2 / 2: the shear rigidity
 *                  (W = G gamma^2 / 2) is G = s_sh (N/m).
 *                  s_uv (Poisson coupling) has no counterpart in the particle
 *                  model and is dropped.
 *   bending[r][0]  k_e at zero curvature for hinge edges along u (r = 0) and
 *                  along v (r = 2), in the hinge energy of Bridson et al. (2003)
 *                  E = k_e l^2 / (2 (A_0 + A_1)) theta^2 / 4 (N m). On a mesh
 *                  bent to curvature kappa this sums to an energy per area of
 *                  (k_e / 4) kappa^2 / 2 (a square grid split into right
 *                  triangles: per cell one hinge with l = a, A_0 + A_1 = a^2,
 *                  theta = kappa a, E = k_e kappa^2 a^2 / 8; equilateral meshes
 *                  give 0.244-0.248 k_e), so the continuum bending rigidity is
 *                  D = k_e / 4. Hinges along v resist curvature along u.
 *   bending[1][0]  the same for hinges at 45 degrees to u and v: a strip cut on
 *                  the bias bends with Bb = k_e / 4 (drape's bias rigidity, the
 *                  third value of -cloth_bend; -cloth_model paper has no such term).
 *   bending[r][i]  k_e at the hinge's curvature theta l / (A_0 + A_1) = 10 i 1/m,
 *                  i = 0..4 (dde.cpp, bending_stiffness: "samples are per 0.05
 *                  cm^-1 = 5 m^-1" of half that curvature), linear between the
 *                  samples and held at the last beyond; ARCSim's force is k_e at
 *                  the current curvature times the angle, a secant rigidity. drape
 *                  uses these only with -cloth_bend_table (KernelBendLaw).
 * The model's warp is taken as the material's u axis (the files do not say which
 * of u and v is the warp). Only the small-strain values of stretching are used:
 * the particle model is linear in them (the measured stiffening at larger strain
 * is not represented). Explicit -cloth_* options override single values. */
#include "clothimpl.h"

typedef struct {
  const char *name, *alias, *use;
  PetscReal   density;                /* kg/m^2                                   */
  PetscReal   s_uu, s_uv, s_vv, s_sh; /* stretching[0] as in the file              */
  PetscReal   ke[3][5];               /* bending: hinges along u, at 45 degrees, along v (N m) at curvature 0, 10, ..., 40 1/m */
} Fabric;

/* clang-format off */
static const Fabric fabrics[] = {
  {"11oz-black-denim", "denim", "jeans, 99% cotton 1% spandex", 0.324, 205.352005, 10.234077, 1013.88629, 53.387184, {{64.196457e-6, 60.286175e-6, 60.943428e-6, 62.433697e-6, 19.824701e-6}, {73.384567e-6, 59.671982e-6, 61.080757e-6, 68.242569e-6, 36.033474e-6}, {96.951576e-6, 107.848228e-6, 113.060738e-6, 120.569740e-6, 79.781021e-6}}},
  {"white-dots-on-blk", "polyester", "tablecloth, 100% polyester", 0.128, 2002.08618, 0.345588, 2027.48559, 19.189022, {{51.713814e-6, 36.506981e-6, 66.360748e-6, 52.729267e-6, 15.221714e-6}, {40.659470e-6, 10.401686e-6, 20.847820e-6, 30.993469e-6, 12.726685e-6}, {31.282822e-6, 22.910311e-6, 26.350384e-6, 30.637762e-6, 16.726685e-6}}},
  {"royal-target", NULL, "pants, 65% cotton 35% polyester", 0.220, 2016.55456, 9.170511, 2034.97644, 104.759674, {{125.409805e-6, 167.284561e-6, 215.412750e-6, 215.090790e-6, 223.861038e-6}, {107.997696e-6, 120.583267e-6, 144.141678e-6, 140.606689e-6, 153.048309e-6}, {125.409805e-6, 167.284561e-6, 215.412750e-6, 215.090790e-6, 227.861038e-6}}},
  {"gray-interlock", NULL, "t-shirt knit, 60% cotton 40% polyester", 0.187, 16.593832, -14.69599, 34.477123, 36.860302, {{23.191698e-6, 32.932217e-6, 34.406498e-6, 39.014420e-6, 23.382786e-6}, {24.749964e-6, 18.651314e-6, 16.370552e-6, 25.095791e-6, 8.860165e-6}, {14.267624e-6, 7.052906e-6, 14.515154e-6, 24.665127e-6, 19.383726e-6}}},
  {"ivory-rib-knit", NULL, "underwear knit, 95% cotton 5% spandex", 0.276, 42.871021, -0.234556, 65.166023, 83.175644, {{46.237591e-6, 63.086697e-6, 83.192772e-6, 97.574425e-6, 80.726685e-6}, {30.015930e-6, 30.097424e-6, 30.172081e-6, 30.648300e-6, 24.726685e-6}, {32.243889e-6, 37.341282e-6, 38.817448e-6, 39.812527e-6, 30.437820e-6}}},
  {"pink-ribbon-brown", NULL, "blanket, 100% polyester", 0.228, 151.503906, 106.02816, 244.830673, 30.250183, {{117.070122e-6, 202.682922e-6, 298.615936e-6, 244.588867e-6, 238.437820e-6}, {87.509773e-6, 36.396919e-6, 103.628098e-6, 91.630119e-6, 97.175949e-6}, {59.774277e-6, 59.260632e-6, 64.199661e-6, 55.017326e-6, 59.221714e-6}}},
  {"tango-red-jet-set", NULL, "jacket, 100% polyester", 0.113, 43.067627, 54.373299, 171.424835, 14.3147, {{14.293814e-6, 8.949391e-6, 30.011126e-6, 36.081490e-6, 18.363136e-6}, {21.951700e-6, 22.446325e-6, 18.408735e-6, 19.598495e-6, 12.071854e-6}, {20.345654e-6, 22.696880e-6, 15.698071e-6, 13.466827e-6, 7.556618e-6}}},
  {"camel-ponte-roma", NULL, "jacket knit, 60% polyester 40% rayon", 0.284, 31.146198, -12.802702, 44.028667, 31.896357, {{36.348366e-6, 49.585537e-6, 45.744080e-6, 47.413387e-6, 20.726685e-6}, {33.013252e-6, 29.744385e-6, 35.103642e-6, 34.041019e-6, 14.439938e-6}, {37.157593e-6, 34.107452e-6, 33.229435e-6, 34.685535e-6, 10.439938e-6}}},
  {"navy-sparkle-sweat", NULL, "sweater, 96% polyester 4% spandex", 0.224, 12.486332, -19.875324, 3.272434, 17.616289, {{59.469658e-6, 37.500004e-6, 35.787308e-6, 35.737106e-6, 21.033506e-6}, {40.072277e-6, 37.446949e-6, 35.206612e-6, 24.871773e-6, 9.033506e-6}, {45.625023e-6, 39.520981e-6, 30.734119e-6, 23.301662e-6, 13.033506e-6}}},
  {"white-swim-solid", NULL, "swimsuit, 87% nylon 13% spandex", 0.204, 47.971176, 6.834521, 104.615456, 60.773663, {{60.237942e-6, 56.357208e-6, 69.698593e-6, 55.305969e-6, 34.705532e-6}, {58.803211e-6, 63.121964e-6, 61.379181e-6, 47.971302e-6, 19.383726e-6}, {51.018833e-6, 50.741455e-6, 50.570576e-6, 50.006001e-6, 24.556618e-6}}},
};
/* clang-format on */
#define NFABRICS ((PetscInt) (sizeof fabrics / sizeof fabrics[0]))

/* "denim (11oz-black-denim), polyester (white-dots-on-blk), royal-target, ..." */
PetscErrorCode ClothFabricList(char *buf, size_t len)
{
  PetscFunctionBeginUser;
  buf[0] = 0;
  for (PetscInt k = 0; k < NFABRICS; k++) {
    char item[96];
    if (fabrics[k].alias)
      PetscCall(PetscSNPrintf(item, sizeof item, "%s%s (%s)", k ? ", " : "", fabrics[k].alias, fabrics[k].name));
    else
      PetscCall(PetscSNPrintf(item, sizeof item, "%s%s", k ? ", " : "", fabrics[k].name));
    PetscCall(PetscStrlcat(buf, item, len));
  }
  PetscFunctionReturn(0);
}

/* Set density and rigidities of c from the named fabric. */
PetscErrorCode ClothSetFabric(Cloth c, const char *name)
{
  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < NFABRICS; k++) {
    const Fabric *f = &fabrics[k];
    PetscBool     match, alias = PETSC_FALSE;
    PetscCall(PetscStrcmp(name, f->name, &match));
    if (f->alias) PetscCall(PetscStrcmp(name, f->alias, &alias));
    if (!match && !alias) continue;
    c->density    = f->density;
    c->stretch[0] = 2 * f->s_uu;
    c->stretch[1] = 2 * f->s_vv;
    c->shear      = f->s_sh; /* see the header: W = k_sh G_uv^2, k_sh = 2 s_sh, G_uv = gamma/2 */
    c->bend_nb    = 5;       /* the table, for -cloth_bend_table */
    c->bend_dk    = 10;
    for (PetscInt r = 0; r < 3; r++) {
      const PetscInt   row[3] = {2, 0, 1}; /* warp, weft, bias: hinges along v, along u, at 45 degrees */
      const PetscReal *ke     = f->ke[row[r]];
      c->bend[r]              = ke[0] / 4; /* bias: what a strip cut at 45 degrees measures */
      for (PetscInt i = 0; i < 5; i++) c->bend_b[r][i] = ke[i] / ke[0];
    }
    PetscCall(PetscSNPrintf(c->fabric, sizeof c->fabric, "%s (%s; Wang, Ramamoorthi & O'Brien 2011)", f->name, f->use));
    PetscFunctionReturn(0);
  }
  {
    char list[1024];
    PetscCall(ClothFabricList(list, sizeof list));
    SETERRQ(c->comm, PETSC_ERR_USER_INPUT, "Unknown fabric \"%s\" for -cloth_fabric; drape's library holds the fabrics with published measurements: %s. For any other fabric give -cloth_density, -cloth_stretch, -cloth_shear and -cloth_bend", name,
            list);
  }
}
