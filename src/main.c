static const char help[] = "drape: how a fabric falls, hangs and drapes, by the particle method (Landovsky).\n"
                           "Usage: mpirun -np N ./build/drape -options_file runs/hang.opts [options]\n"
                           "Integrators: -ts_type euler | basicsymplectic | beuler | rk | ssp. See README.md.\n\n";

#include <drape.h>
#include <simulation.h>

static PetscErrorCode Run(void)
{
  Simulation sim;

  PetscFunctionBeginUser;
  PetscCall(PetscLogStagePush(drape_log.setup));
  PetscCall(SimulationCreate(PETSC_COMM_WORLD, &sim));
  PetscCall(SimulationSetFromOptions(sim));
  PetscCall(SimulationSetUp(sim));
  PetscCall(PetscLogStagePop());
  PetscCall(SimulationRun(sim));
  PetscCall(SimulationDestroy(&sim));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr;

  PetscCall(PetscInitialize(&argc, &argv, NULL, help));
  PetscCall(DrapeInitialize());
  ierr = Run();
  PetscCall(DrapeFinalize());
  PetscCall(PetscFinalize());
  return ierr ? 1 : 0;
}
