// Unit tests of adaptive refinement as a strategy of the loop over meshes (AdaptiveRefinement, adapt.h),
// fed with synthetic indicators (eta_T^2 = |T|^2 / (|x_T - x0|^2 + 0.01), which the refinement of the
// cells near x0 reduces) instead of the estimate, on a 2D Signorini scene pressed onto Gamma_C, P1 and
// CR. The run on all ranks, redistributed whenever the cells are not perfectly balanced
// (-adapt_imbalance 1), is compared with the same run on one rank (PETSC_COMM_SELF, the independent
// computation): every step must have the same cells and DOFs, the final solution the same energy. Also:
// every step marks and refines, eta falls, the last solution satisfies the KKT conditions with part of
// Gamma_C active, on more than one rank some step redistributes, and -adapt_tol stops the run at the first step whose eta is below it. Runs on 1 and 2
// ranks (ctest).
#include "signorini/adapt.h"
#include "signorini/mesh.h"
#include "signorini/stages.h"
#include "unit_check.h"

using namespace signorini;

struct Run {
  std::vector<AdaptRow> rows;
  PetscReal             energy = 0, kkt = 0;
  PetscInt              active = 0;
};

static PetscErrorCode Indicators(const MeshSolution &m, std::vector<PetscReal> &eta2, PetscReal &eta, double &seconds)
{
  const PetscReal x0[2] = {0.3, 0.0};
  PetscFunctionBeginUser;
  eta2.resize(m.space.NumCells());
  PetscReal sum = 0;
  for (PetscInt c = 0; c < m.space.NumCells(); ++c) {
    CellGeometry g;
    ComputeCellGeometry(m.space.dim, m.space.X(c), g);
    const PetscReal r2 = (g.centroid[0] - x0[0]) * (g.centroid[0] - x0[0]) + (g.centroid[1] - x0[1]) * (g.centroid[1] - x0[1]);
    eta2[c]            = g.volume * g.volume / (r2 + 0.01);
    sum += eta2[c];
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &sum, 1, MPIU_REAL, MPI_SUM, PetscObjectComm((PetscObject)m.u)));
  eta     = std::sqrt(sum);
  seconds = 0;
  PetscFunctionReturn(0);
}

static PetscErrorCode AdaptRun(MPI_Comm comm, Element element, const AdaptOptions &a, Run &run)
{
  DM              mesh;
  MeshInfo        info;
  MeshOptions     mo;
  Problem         problem;
  PipelineOptions po;
  PetscFunctionBeginUser;
  mo.faces[0] = 6, mo.faces[1] = 4, mo.diagonal = Diagonal::Backslash;
  PetscCall(MeshCreate(comm, mo, &mesh, info));
  // Dirichlet on top (3), contact on the bottom (1), pressed down by f.
  PetscCall(unit::MakeProblem(comm, 2, {{3}, {1}, "-20", "0", "0.05", "0"}, problem));
  po.element = element;
  po.kktHint = false;
  {
    AdaptiveRefinement strategy(mesh, problem, po, a, 2, Indicators);
    PetscCall(DMDestroy(&mesh));
    PetscCall(SolveMeshes(problem, strategy));
    run.rows   = strategy.rows;
    run.energy = strategy.finest.result.energy;
    run.kkt    = strategy.finest.result.kktRelative;
    run.active = strategy.finest.result.active;
    PetscCall(strategy.finest.Destroy());
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode TestElement(unit::Checker &ck, Element element)
{
  PetscMPIInt       size;
  const std::string tag = ElementName(element);
  AdaptOptions      a;
  Run               par, ser, stopped;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(PETSC_COMM_WORLD, &size));
  a.steps     = 3;
  a.theta     = 0.5;
  a.imbalance = 1.0;
  PetscCall(AdaptRun(PETSC_COMM_WORLD, element, a, par));
  PetscCall(AdaptRun(PETSC_COMM_SELF, element, a, ser));
  bool same = par.rows.size() == ser.rows.size(), refines = par.rows.size() == 4, falls = true, redistributed = false;
  for (size_t k = 0; same && k < par.rows.size(); ++k) same = par.rows[k].cells == ser.rows[k].cells && par.rows[k].dofs == ser.rows[k].dofs && par.rows[k].marked == ser.rows[k].marked;
  for (size_t k = 0; k + 1 < par.rows.size(); ++k) {
    refines       = refines && par.rows[k].marked > 0 && par.rows[k + 1].cells > par.rows[k].cells;
    falls         = falls && par.rows[k + 1].eta < par.rows[k].eta;
    redistributed = redistributed || par.rows[k].redistributed;
  }
  ck.Check(refines, tag + ": 3 steps, each marks cells and refines them", "%d rows", (int)par.rows.size());
  ck.Check(same, tag + ": the same cells, DOFs and marked cells at every step as on one rank");
  ck.Check(std::fabs(par.energy - ser.energy) <= 1e-8 * std::fabs(ser.energy), tag + ": the same final energy as on one rank", "%.15g vs %.15g", (double)par.energy, (double)ser.energy);
  ck.Check(falls, tag + ": the indicators' eta falls from step to step");
  ck.Check(par.kkt < 1e-6 && par.active > 0, tag + ": the last solution satisfies the KKT conditions, part of Gamma_C active", "relative KKT residual %g, %d active", (double)par.kkt, (int)par.active);
  ck.Check(size == 1 || redistributed, tag + ": on more than one rank an unbalanced refined mesh is redistributed");
  a.tol = par.rows[1].eta * (1 + 1e-9);
  PetscCall(AdaptRun(PETSC_COMM_WORLD, element, a, stopped));
  ck.Check(stopped.rows.size() == 2 && stopped.rows[1].cells == par.rows[1].cells, tag + ": -adapt_tol stops at the first step with eta below it", "%d rows", (int)stopped.rows.size());
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  unit::Checker ck;
  PetscCall(StagesRegister());
  for (Element e : {Element::P1, Element::CR}) {
    const PetscErrorCode ierr = TestElement(ck, e);
    if (ierr) ck.PetscFailure(ierr, ElementName(e));
  }
  const int status = ck.Finish();
  PetscCall(PetscFinalize());
  return status;
}
