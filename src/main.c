#define _POSIX_C_SOURCE 200809L /* unsetenv */
static const char help[] = "drape: how a fabric falls, hangs and drapes, by the particle method (Landovsky).\n"
                           "Usage: mpirun -np N ./build/drape -options_file runs/hang.opts [options]\n"
                           "Integrators: -ts_type euler | basicsymplectic | drapebe | rk | ssp. See README.md.\n\n";

#include <drape.h>
#include <simulation.h>
#include <signal.h>
#include <stdlib.h>

/* Exit status: 0 done, 1 error, 75 (EX_TEMPFAIL) stopped by SIGTERM, SIGINT, SIGHUP or SIGPIPE with a
 * checkpoint written: a batch script may requeue with -restart; 1 too for such a stop
 * that -restart cannot continue (bending friction), so that nothing requeues it. */
static PetscErrorCode Run(PetscBool *interrupted, PetscBool *restartable)
{
  Simulation sim;

  PetscFunctionBeginUser;
  PetscCall(DrapeReportOptionsFiles(PETSC_COMM_WORLD));
  PetscCall(DrapeCheckRanksAgree(PETSC_COMM_WORLD));
  PetscCall(DrapeCheckMPIIONames(PETSC_COMM_WORLD));
  PetscCall(DrapeCheckLogView(PETSC_COMM_WORLD));
  PetscCall(PetscLogStagePush(drape_log.setup));
  PetscCall(SimulationCreate(PETSC_COMM_WORLD, &sim));
  PetscCall(SimulationSetFromOptions(sim));
  PetscCall(SimulationSetUp(sim));
  PetscCall(PetscLogStagePop());
  PetscCall(SimulationRun(sim));
  PetscCall(SimulationInterrupted(sim, interrupted, restartable));
  PetscCall(SimulationDestroy(&sim));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr;
  PetscBool      interrupted = PETSC_FALSE, restartable = PETSC_TRUE;
  int            petsc_argc = argc;
  char         **petsc_argv = argv, *without_files[] = {argv[0], (char *) "-skip_petscrc", NULL};

  /* a write past the file-size limit (ulimit -f) fails with EFBIG, and a sentence,
   * instead of killing drape with SIGXFSZ (the output checks the limit before each
   * frame, so that the frames written stay readable) */
  (void) signal(SIGXFSZ, SIG_IGN);
  /* MPI first: the options files are checked before PETSc reads them (PETSc's own
   * reader cannot report a bad one in a sentence), and a bad one keeps them away from
   * PetscInitialize, so that Run() can say what is wrong */
  if (MPI_Init(&argc, &argv) != MPI_SUCCESS) return 1;
  if (!DrapeCheckOptionsFiles(argc, argv)) {
    petsc_argc = 2;
    petsc_argv = without_files;
    (void) unsetenv("PETSC_OPTIONS");
  }
  PetscCall(PetscInitialize(&petsc_argc, &petsc_argv, NULL, help));
  PetscCall(DrapeInitialize());
  /* a closed stdout (drape | head) makes prints fail quietly instead of killing the
   * run; in the time loop SIGPIPE stops it like SIGTERM, with a checkpoint */
  (void) signal(SIGPIPE, SIG_IGN);
  ierr = Run(&interrupted, &restartable);
  /* a failure only some ranks saw would leave the others waiting: that ends the whole
   * job (MPI_Abort; the frames written so far are on disk) */
  if (ierr) PetscCall(DrapeEndWithError(ierr));
  PetscCall(DrapeFinalize());
  PetscCall(PetscFinalize());
  if (MPI_Finalize() != MPI_SUCCESS) return 1;
  return ierr ? 1 : (interrupted ? (restartable ? 75 : 1) : 0);
}
