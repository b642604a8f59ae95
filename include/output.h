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

/* Restart (src/io/restart.c). RestartInsertOptions puts the options stored in a
 * drape file into the options database under the command line's own (the command
 * line wins); a missing, truncated, foreign or damaged file ends with one sentence.
 * RestartLoad reads the last complete frame into x, v (owned order), with its time
 * and step, and the times of all complete frames (caller frees). Both collective
 * (rank 0 checks the file, every rank reads the frame). */
PETSC_EXTERN PetscErrorCode RestartInsertOptions(MPI_Comm, const char file[]);
PETSC_EXTERN PetscErrorCode RestartLoad(MPI_Comm, const char file[], Cloth, PetscScalar *x, PetscScalar *v, PetscReal *t, PetscInt *step, PetscInt *nframes, PetscReal **times);
/* Continue writing into an existing file after its first nframes frames (times),
 * if it is the output file (by identity, not by name). Not collective. */
PETSC_EXTERN PetscErrorCode OutputSetAppend(Output, const char file[], PetscInt nframes, const PetscReal times[]);
