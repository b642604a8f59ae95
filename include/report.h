/* The numbers a run reports about itself (start-up: lattice, material, stability
 * limits, integrator; end: steps, wall time, solver statistics, strain, drape
 * coefficient), by name, for programs rather than people: written as attributes of
 * the output file's root (OutputWriteReport) and, with -drape_json, as one JSON
 * line on standard output. The printed prose says the same for people. */
#pragma once

#include <petscviewer.h>

typedef struct _p_Report *Report;

/* Not collective: every rank keeps the same entries, rank 0 prints them. */
PETSC_EXTERN PetscErrorCode ReportCreate(MPI_Comm, Report *);
PETSC_EXTERN PetscErrorCode ReportDestroy(Report *);
/* Set (or replace) an entry; names are [a-z0-9_], entries keep the order of their
 * first setting. Not collective. */
PETSC_EXTERN PetscErrorCode ReportSetReal(Report, const char name[], PetscReal);
PETSC_EXTERN PetscErrorCode ReportSetInt(Report, const char name[], PetscInt);
PETSC_EXTERN PetscErrorCode ReportSetBool(Report, const char name[], PetscBool);
PETSC_EXTERN PetscErrorCode ReportSetString(Report, const char name[], const char value[]);
/* Set an entry and print the same value on an ASCII viewer with `format` (its one
 * conversion for the value: a real's %g, %e or %f, "%" PetscInt_FMT, %s), so that
 * the prose and the report cannot say different numbers; viewer NULL: set it only.
 * ReportViewPercent prints 100 x the value (a fraction) and reports the fraction.
 * Collective on the viewer (rank 0 prints). */
PETSC_EXTERN PetscErrorCode ReportViewReal(Report, PetscViewer, const char name[], const char format[], PetscReal);
PETSC_EXTERN PetscErrorCode ReportViewPercent(Report, PetscViewer, const char name[], const char format[], PetscReal);
PETSC_EXTERN PetscErrorCode ReportViewInt(Report, PetscViewer, const char name[], const char format[], PetscInt);
PETSC_EXTERN PetscErrorCode ReportViewString(Report, PetscViewer, const char name[], const char format[], const char value[]);
/* Entry k (0 <= k < n): its name and type (PETSC_REAL, PETSC_INT, PETSC_BOOL or
 * PETSC_STRING) and value (the one of its type). Not collective. */
PETSC_EXTERN PetscErrorCode ReportGetSize(Report, PetscInt *n);
PETSC_EXTERN PetscErrorCode ReportGetEntry(Report, PetscInt k, const char **name, PetscDataType *, PetscReal *r, PetscInt *i, const char **s);
/* One line: a JSON object of every entry (reals that are not finite, or at least
 * PETSC_INFINITY, as null), printed by
 * rank 0. Collective. */
PETSC_EXTERN PetscErrorCode ReportPrintJSON(Report);
/* This process's CPU time so far, s: user + system time of all its threads
 * (getrusage RUSAGE_SELF), so a loaded machine, which stretches wall time, does not
 * change it much. Not collective. */
PETSC_EXTERN PetscErrorCode ReportCPUTime(PetscLogDouble *seconds);
/* This process's peak resident memory so far, bytes: VmHWM of /proc/self/status
 * (the high-water mark of its own address space since exec) where Linux gives it,
 * else getrusage's ru_maxrss (which on Linux also counts the RSS of the process it
 * was forked from, up to its exec). Not collective. */
PETSC_EXTERN PetscErrorCode ReportPeakMemory(PetscLogDouble *bytes);
