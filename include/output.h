/* HDF5 frames (natural lattice order), an XDMF index beside them for ParaView. */
#pragma once

#include <cloth.h>
#include <solid.h>
#include <report.h>

typedef struct _p_Output *Output;

/* Not collective. */
PETSC_EXTERN PetscErrorCode OutputCreate(MPI_Comm, Output *);
/* -output_file, -output_interval (simulated s), -output_steps; the file is checked on
 * every rank (its directory takes a new file; it is not its own XDMF index nor a
 * file the run reads), nothing is opened. Collective. */
PETSC_EXTERN PetscErrorCode OutputSetFromOptions(Output);
/* Not collective. */
PETSC_EXTERN PetscErrorCode OutputEnabled(Output, PetscBool *);
/* Open the file and write every option as given, the version and the solid's
 * triangles. Collective (MPI-IO). */
PETSC_EXTERN PetscErrorCode OutputOpen(Output, Cloth, Solid);
/* Is a frame due at (step, t)? The first frame is always due. Not collective. */
PETSC_EXTERN PetscErrorCode OutputFrameDue(Output, PetscInt step, PetscReal t, PetscBool *);
/* Write one frame and flush it to disk: a run killed later keeps it readable.
 * Collective (MPI-IO). */
PETSC_EXTERN PetscErrorCode OutputWriteFrame(Output, Cloth, PetscInt step, PetscReal t, const PetscScalar *x, const PetscScalar *v, const ClothEnergies *);
/* Step of the last frame written (-1: none). Not collective. */
PETSC_EXTERN PetscErrorCode OutputLastStep(Output, PetscInt *);
/* Every entry of the report as an attribute of the file's root (replacing the
 * ones of the same name). Collective (MPI-IO), as is OutputDestroy (it closes the
 * file). */
PETSC_EXTERN PetscErrorCode OutputWriteReport(Output, Report);
PETSC_EXTERN PetscErrorCode OutputDestroy(Output *);

/* Continue writing into an existing file after its first nframes frames (times),
 * if it is the output file (by identity, not by name). Not collective. */
PETSC_EXTERN PetscErrorCode OutputSetAppend(Output, const char file[], PetscInt nframes, const PetscReal times[]);
/* The file to write when -output_file does not name one (a restart continues its
 * own file); before OutputSetFromOptions. Not collective. */
PETSC_EXTERN PetscErrorCode OutputSetDefaultFile(Output, const char file[]);
/* -output_file as given (NULL: no output). Not collective. */
PETSC_EXTERN PetscErrorCode OutputGetFileName(Output, const char **);

/* Restart (src/io/restart.c): -restart FILE continues the run stored in a drape file
 * from its last complete frame. Create and Destroy: not collective. */
typedef struct _p_Restart  *Restart;
PETSC_EXTERN PetscErrorCode RestartCreate(MPI_Comm, Restart *);
PETSC_EXTERN PetscErrorCode RestartDestroy(Restart *);
/* -restart: the file is checked (rank 0; a missing, truncated, foreign or damaged file
 * ends with one sentence) and the options stored in it go into the options database
 * under the command line's own (the command line wins; a cloth of another material or
 * geometry is refused); the output continues that file unless -output_file names
 * another. Before the other components read their options. Collective. */
PETSC_EXTERN PetscErrorCode RestartSetFromOptions(Restart, Output);
/* Not collective. */
PETSC_EXTERN PetscErrorCode RestartEnabled(Restart, PetscBool *);
/* Can -restart continue a run of this cloth? Not with bending friction, whose plastic
 * state the frames do not hold. Not collective. */
PETSC_EXTERN PetscErrorCode RestartSupported(Cloth, PetscBool *);
/* Read the last complete frame into x, v (owned order; nothing without -restart) and
 * let the output append after the frames before it. Collective (every rank reads). */
PETSC_EXTERN PetscErrorCode RestartLoad(Restart, Cloth, Output, PetscScalar *x, PetscScalar *v);
/* Time and step the run starts from (0, 0 without -restart). Not collective. */
PETSC_EXTERN PetscErrorCode RestartGetStart(Restart, PetscReal *t, PetscInt *step);
/* After a stop by `signal` at (step, t) with the last frame written: how to continue
 * it, on viewer. Collective on the viewer. */
PETSC_EXTERN PetscErrorCode RestartViewStop(Restart, Cloth, Output, PetscViewer, const char signal[], PetscInt step, PetscReal t);
