/* The rigid solid the cloth drapes over, and contact with it.
 *
 * A Solid is a body, either a closed triangle mesh (read from an OFF/OBJ/STL/PLY file
 * with CGAL's I/O and held in a CGAL AABB tree) or a generated primitive (box,
 * sphere, capped cylinder: exact closed-form distance, no tree), and optionally a
 * plane. Queries return the signed distance to the nearest of them (positive
 * outside) and the outward normal there. */
#pragma once

#include <petscsys.h>

/* A closed triangle mesh in a CGAL AABB tree (src/solid/aabb.cxx); each rank holds
 * its own. Not collective. */
typedef struct _p_SolidMesh *SolidMesh;
PETSC_EXTERN PetscErrorCode  SolidMeshCreateFromFile(const char path[], const PetscReal A[9], const PetscReal b[3], SolidMesh *);
PETSC_EXTERN PetscErrorCode  SolidMeshGetBoundingBox(SolidMesh, PetscReal lo[3], PetscReal hi[3]);
PETSC_EXTERN PetscErrorCode  SolidMeshGetSize(SolidMesh, PetscInt *nv, PetscInt *nt);
PETSC_EXTERN PetscErrorCode  SolidMeshGetTriangles(SolidMesh, PetscReal *xyz); /* 9 per triangle */
PETSC_EXTERN PetscErrorCode  SolidMeshQuery(SolidMesh, const PetscReal p[3], PetscReal closest[3], PetscBool *inside);
/* The first triangle met on the segment p0 -> p1: p0 + t (p1 - p0), and the
 * triangle's unit normal turned against the motion; *hit false if none. */
PETSC_EXTERN PetscErrorCode SolidMeshSweep(SolidMesh, const PetscReal p0[3], const PetscReal p1[3], PetscReal *t, PetscReal normal[3], PetscBool *hit);
PETSC_EXTERN PetscErrorCode SolidMeshDestroy(SolidMesh *);

typedef struct _p_Solid    *Solid;
PETSC_EXTERN PetscErrorCode SolidCreate(MPI_Comm, Solid *);
/* -solid_type, -solid_file, -solid_scale, -solid_rotate, -solid_translate,
 * -solid_size, -solid_radius, -solid_height, -solid_resolution, -solid_plane,
 * -solid_floor. SolidSetFromOptions, SolidSetUp (every rank reads the mesh file; a
 * failure is raised together) and SolidView are collective; SolidCreate,
 * SolidDestroy and the queries below are not. */
PETSC_EXTERN PetscErrorCode SolidSetFromOptions(Solid);
PETSC_EXTERN PetscErrorCode SolidSetUp(Solid);
PETSC_EXTERN PetscErrorCode SolidView(Solid, PetscViewer);
PETSC_EXTERN PetscErrorCode SolidDestroy(Solid *);
/* No body at all: a scene without a solid runs no contact code. */
PETSC_EXTERN PetscErrorCode SolidIsEmpty(Solid, PetscBool *);
/* Does the box [lo, hi] come within `grow` of a body? (Cheap culling test.) */
PETSC_EXTERN PetscBool SolidBoxNear(Solid, const PetscReal lo[3], const PetscReal hi[3], PetscReal grow);
/* Signed distance of p to the nearest body (< 0 inside) and the outward normal. */
PETSC_EXTERN PetscErrorCode SolidQuery(Solid, const PetscReal p[3], PetscReal *distance, PetscReal normal[3]);
/* The first point where the segment p0 -> p1 (a particle's step) enters a body or
 * the plane from outside: p0 + t (p1 - p0), with the surface's unit normal there
 * (turned against the motion on a mesh); *hit false if it enters none. mesh_only:
 * the mesh body only. Not collective. */
PETSC_EXTERN PetscErrorCode SolidSweep(Solid, const PetscReal p0[3], const PetscReal p1[3], PetscBool mesh_only, PetscReal *t, PetscReal normal[3], PetscBool *hit);
/* Triangles of the mesh bodies for pictures (9 reals each; caller frees). */
PETSC_EXTERN PetscErrorCode SolidGetTriangles(Solid, PetscInt *ntri, PetscReal **xyz);

/* Contact of the cloth's particles with the solid (src/solid/contact.c).
 *   sticky        the paper's condition: a particle that reaches the surface stops (v = 0)
 *   friction      Coulomb: sticks while the tangential impulse is below mu times
 *                 the normal one, slides with kinetic friction mu otherwise
 *   frictionless  only the normal velocity into the solid is removed
 * A particle is in contact when it is closer than -contact_thickness to the solid. */
typedef enum {
  CONTACT_STICKY,
  CONTACT_FRICTION,
  CONTACT_FRICTIONLESS
} ContactMode;

typedef struct _p_Contact  *Contact;
PETSC_EXTERN PetscErrorCode ContactCreate(MPI_Comm, Solid, Contact *);
/* -contact_mode, -contact_thickness, -contact_friction (-contact_stick_velocity:
 * include/contactsolve.h).
 * ContactSetFromOptions and ContactView are collective; ContactCreate,
 * ContactDestroy, ContactGetMode are not. */
PETSC_EXTERN PetscErrorCode ContactSetFromOptions(Contact);
PETSC_EXTERN PetscErrorCode ContactView(Contact, PetscViewer);
PETSC_EXTERN PetscErrorCode ContactDestroy(Contact *);
/* mode, Coulomb coefficient (0 unless friction) */
PETSC_EXTERN PetscErrorCode ContactGetMode(Contact, ContactMode *, PetscReal *friction);
/* After a step: move particles closer than the thickness back onto the contact
 * surface and constrain their velocity by the mode; n particles, 3 entries each,
 * pinned particles skipped. Returns the deepest penetration below the contact
 * surface before the correction (max over all ranks), and the number of particles
 * in contact. Particles outside the solid's box are not queried. h: for schemes
 * whose position update used the new velocity (symplectic and backward Euler),
 * the step, so that the position follows the corrected velocity (a particle held
 * by static friction does not creep); 0 otherwise. held (n, or NULL): the
 * particles sticky contact holds (in contact, velocity zero). Collective (the deepest
 * penetration and the count are reduced), as is ContactCheckInitial. */
PETSC_EXTERN PetscErrorCode ContactProject(Contact, PetscInt n, PetscScalar *x, PetscScalar *v, const PetscReal *mass, const PetscBool *pinned, PetscReal h, PetscReal *depth, PetscInt *ncontact, PetscReal impulse[3], PetscBool *held);
/* Continuous contact for a particle's step p0 -> p1 (p0 outside the solid; clear: a
 * lower bound of its distance there, 0 if unknown). The caller's answer at the end
 * point (distance dist and the closest point's normal, taken as a contact when
 * dist < limit: back onto the contact surface along that normal) misses a step
 * through a thin part of the solid, or puts the particle out on its far side. Then
 * *hit is true, with q where the step entered the solid and nf the surface's normal
 * there: the particle belongs on the plane through q at the contact thickness. Not
 * collective. */
PETSC_EXTERN PetscErrorCode ContactSweep(Contact, const PetscReal p0[3], const PetscReal p1[3], PetscReal clear, PetscReal dist, const PetscReal normal[3], PetscReal limit, PetscBool *hit, PetscReal q[3], PetscReal nf[3]);
/* Refuse an initial state with particles inside the solid (one sentence). It also
 * records the positions the first step starts from: ContactProject tests each step
 * from where the last one (or this) left the particles to where it ends, so that a
 * particle cannot pass through a thin part of the solid in one step. */
PETSC_EXTERN PetscErrorCode ContactCheckInitial(Contact, PetscInt n, const PetscScalar *x);
/* Distance of owned particle k (of n) at x to the solid, as SolidQuery, through a
 * per-particle cache shared with ContactProject: a particle that moved less than its
 * last clearance is not queried again. Where the answer is larger than twice the
 * contact thickness it may be a lower bound, and the normal is not set. */
PETSC_EXTERN PetscErrorCode ContactDistance(Contact, PetscInt k, PetscInt n, const PetscReal x[3], PetscReal *dist, PetscReal normal[3]);
PETSC_EXTERN PetscErrorCode ContactGetThickness(Contact, PetscReal *);
