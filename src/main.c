static const char help[] = "drape: how a fabric falls, hangs and drapes, by the particle method (Landovsky).\n"
                           "Usage: mpirun -np N ./build/drape -options_file runs/hang.opts [options]\n"
                           "Integrators: -ts_type euler | basicsymplectic | beuler | rk | ssp. See README.md.\n\n";

#include <drape.h>
#include <simulation.h>

/* Exit status: 0 done, 1 error, 75 (EX_TEMPFAIL) stopped by SIGTERM/SIGINT with a
 * checkpoint written: a batch script may requeue with -restart. */
static PetscErrorCode Run(PetscBool *interrupted)
{
  Simulation sim;

  PetscFunctionBeginUser;
  PetscCall(PetscLogStagePush(drape_log.setup));
  PetscCall(SimulationCreate(PETSC_COMM_WORLD, &sim));
  PetscCall(SimulationSetFromOptions(sim));
  PetscCall(SimulationSetUp(sim));
  PetscCall(PetscLogStagePop());
  PetscCall(SimulationRun(sim));
  PetscCall(SimulationInterrupted(sim, interrupted));
  PetscCall(SimulationDestroy(&sim));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr;
  PetscBool      interrupted = PETSC_FALSE;

  PetscCall(PetscInitialize(&argc, &argv, NULL, help));
  PetscCall(DrapeInitialize());
  ierr = Run(&interrupted);
  PetscCall(DrapeFinalize());
  if (ierr) {
    /* an error that not every rank saw would leave the others waiting in a
     * collective: end the whole job (the frames written so far are on disk).
     * A user error raised on all ranks together ends normally. */
    PetscMPIInt size;
    PetscCallMPI(MPI_Comm_size(PETSC_COMM_WORLD, &size));
    if (size > 1 && !DrapeErrorIsCollective()) PETSCABORT(PETSC_COMM_WORLD, ierr);
  }
  PetscCall(PetscFinalize());
  return ierr ? 1 : (interrupted ? 75 : 0);
}
