static const char help[] =
  "signorini: the Signorini (unilateral contact) problem -div(kappa grad u) = f with u >= psi on Gamma_C,\n"
  "discretized with Crouzeix-Raviart (-space cr) or conforming P1 (-space p1) elements on a DMPlex mesh,\n"
  "solved with SNESVI reduced-space Newton and CG + hypre BoomerAMG.\n\n"
  "Sample runs:\n"
  "  signorini -options_file petsc-options/paper-5.1 -space cr -box_faces 64\n"
  "  mpirun -n 2 signorini -options_file petsc-options/manufactured-2d -space p1 -refine 2 -summary run.json\n"
  "  signorini -options_file petsc-options/manufactured-3d -snes_monitor -ksp_converged_reason -log_view\n\n";

#include "signorini/adapt.h"
#include "signorini/assembly.h"
#include "signorini/contact.h"
#include "signorini/error.h"
#include "signorini/mesh.h"
#include "signorini/nested.h"
#include "signorini/options.h"
#include "signorini/output.h"
#include "signorini/pipeline.h"
#include "signorini/problem.h"
#include "signorini/report.h"
#include "signorini/sizes.h"
#include "signorini/space.h"
#include "signorini/stages.h"
#include "signorini/startup.h"
#include "signorini/strategy.h"
#include "signorini/study.h"

#include <cstdio>
#include <functional>

using namespace signorini;

// Options of every component, read before any work so that -help lists them all.
struct Settings {
  MeshOptions     mesh;
  Element         element = Element::CR;
  Problem         problem;
  AssemblyOptions assembly;
  PetscInt        errorDegree = 6;
  std::string     summaryFile;
  OutputOptions   output;
  StudyOptions    study;
  SolveOptions    solve;
  NestedOptions   nested;
  EstimateOptions estimate;
  AdaptOptions    adapt;
};

// Under -help every component lists its options whatever else is on the command line: an error of one
// component (an incomplete scene, a bad value) must not hide the options of the others.
static PetscErrorCode ReadSettings(MPI_Comm comm, Settings &s, bool help)
{
  const std::function<PetscErrorCode()> readers[] = {
    [&] { return MeshOptionsFromCommandLine(comm, s.mesh); },
    [&] { return ElementFromCommandLine(comm, s.element); },
    [&] { return ProblemFromCommandLine(comm, s.problem); },
    [&] { return AssemblyOptionsFromCommandLine(comm, s.assembly); },
    [&] { return ErrorOptionsFromCommandLine(comm, s.errorDegree); },
    [&] { return ReportOptionsFromCommandLine(comm, s.summaryFile); },
    [&] { return OutputOptionsFromCommandLine(comm, s.element, s.problem, s.output); },
    [&] { return StudyOptionsFromCommandLine(comm, s.problem, s.study); },
    [&] { return SolveOptionsFromCommandLine(comm, s.solve); },
    [&] { return NestedOptionsFromCommandLine(comm, s.nested); },
    [&] { return EstimateOptionsFromCommandLine(comm, s.estimate); },
    [&] { return AdaptOptionsFromCommandLine(comm, s.adapt); },
  };
  PetscFunctionBeginUser;
  for (const auto &read : readers) {
    const PetscErrorCode ierr = read();
    if (!help) PetscCall(OptionsAsInputError(comm, ierr));
  }
  PetscFunctionReturn(0);
}

// PETSc registers a package (its types, events and options) when the package's first object is created.
// Done here, that one-time cost stays out of the first mesh's set-up and solve, so that the first row of a
// study or of an adaptive run costs what a later mesh of its size would: error against run time compares
// such rows between runs, each element's study rows after the first element's in one process.
static PetscErrorCode InitializePackages()
{
  PetscFunctionBeginUser;
  PetscCall(ISInitializePackage());
  PetscCall(VecInitializePackage());
  PetscCall(MatInitializePackage());
  PetscCall(PetscSFInitializePackage());
  PetscCall(DMInitializePackage());
  PetscCall(PCInitializePackage());
  PetscCall(KSPInitializePackage());
  PetscCall(SNESInitializePackage());
  PetscFunctionReturn(0);
}

// Options of this program that the run had no use for, each with the reason. PETSc lists its own unused
// options (WarnUnusedOptions), but every component reads ours up front, so a tuning option that cannot
// apply to this scene or mesh would otherwise pass unseen, like a mistyped one.
static PetscErrorCode WarnNotApplied(MPI_Comm comm, std::initializer_list<const char *> names, const char *why)
{
  PetscFunctionBeginUser;
  for (const char *name : names) {
    char      value[256] = "";
    PetscBool set;
    PetscCall(PetscOptionsGetString(NULL, NULL, name, value, sizeof(value), &set));
    if (set) PetscCall(PetscPrintf(comm, "signorini: warning: option %s%s%s was not used (%s)\n", name, value[0] ? " " : "", value, why));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode WarnNotAppliedOptions(MPI_Comm comm, const Settings &s, bool nestedLevels)
{
  PetscFunctionBeginUser;
  if (!s.problem.HasContact())
    PetscCall(WarnNotApplied(comm, {"-amg_reuse", "-amg_reuse_max_changed", "-vi_inexact_rtol", "-vi_pc_type", "-vi_release_theta", "-nested", "-nested_levels", "-solve_to", "-solve_to_rtol", "-solve_to_fraction"}, "the scene has no contact part: it is one linear solve"));
  else if (!nestedLevels && s.adapt.steps == 0 && s.study.levels == 0)
    PetscCall(WarnNotApplied(comm, {"-nested_levels", "-solve_to", "-solve_to_rtol", "-solve_to_fraction"}, s.nested.enabled ? "no nested iteration: the mesh has no coarser refinement levels" : "no nested iteration: -nested 0"));
  if (s.assembly.centroid) PetscCall(WarnNotApplied(comm, {"-load_quadrature_degree"}, "-load_quadrature centroid is the one-point rule"));
  if (!s.mesh.file.empty()) PetscCall(WarnNotApplied(comm, {"-box_faces", "-box_lower", "-box_upper", "-box_diagonal", "-box_coarsen"}, "the mesh is read from -mesh_file"));
  if (s.study.levels > 0 && s.study.referenceRefine == 0) PetscCall(WarnNotApplied(comm, {"-reference_space"}, "the study has no reference: -reference_refine 0"));
  // Data of a boundary part the scene does not have (0, what the scene files give for every part, is no data)
  if (s.problem.contact.empty() && !s.problem.psi->IsZero()) PetscCall(WarnNotApplied(comm, {"-psi"}, "the scene has no contact part, -bc_contact"));
  if (s.problem.neumann.empty() && !s.problem.g->IsZero()) PetscCall(WarnNotApplied(comm, {"-g"}, "the scene has no Neumann part, -bc_neumann; boundary faces in no part have kappa du/dn = 0"));
  if (s.problem.dirichlet.empty() && !s.problem.uD->IsZero()) PetscCall(WarnNotApplied(comm, {"-u_D"}, "the scene has no Dirichlet part, -bc_dirichlet"));
  PetscFunctionReturn(0);
}

static PetscErrorCode Run(MPI_Comm comm)
{
  Settings       s;
  Report         report;
  DM             mesh;
  MeshInfo       meshInfo;
  Output         output; // removes its temporary file if the run ends before OutputEnd
  PetscLogDouble start;
  PetscBool      help = PETSC_FALSE;
  PetscFunctionBeginUser;
  PetscCall(InitializePackages()); // process start-up, like PetscInitialize: not in the run's time
  PetscCall(PetscTime(&start));
  PetscCall(StagesRegister());
  PetscCall(PetscOptionsHasHelp(NULL, &help));
  PetscCall(ReadSettings(comm, s, help));
  if (help) {
    (void)SolverOptionsHelp(comm); // lists what it can; -help exits 0 whatever the options say
    PetscFunctionReturn(0);
  }
  PetscCall(CheckUnknownOptions(comm)); // a mistyped option fails now, not after the run
  PetscCall(CheckSolverOptions(comm, s.problem.HasContact())); // and one the solve cannot use, before the mesh

  // mesh -> space -> assembly -> solve -> errors -> report -> output
  const bool adaptive = s.adapt.steps > 0;
  if (adaptive && s.study.levels > 0) SIGNORINI_INPUT_ERROR(comm, "options -adapt_steps and -study_levels: a run refines adaptively or makes a convergence study, not both");
  // The other -adapt_* options shape an adaptive run: given without one, they would be silently ignored.
  for (const char *name : {"-adapt_theta", "-adapt_tol", "-adapt_max_dofs", "-adapt_imbalance", "-adapt_refinement", "-adapt_reference_steps"}) {
    PetscBool given;
    PetscCall(PetscOptionsHasName(NULL, NULL, name, &given));
    if (given && !adaptive) SIGNORINI_INPUT_ERROR(comm, "option %s: applies to adaptive refinement only; give -adapt_steps K too", name);
  }
  PetscBool referenceDofs;
  PetscCall(PetscOptionsHasName(NULL, NULL, "-adapt_reference_dofs", &referenceDofs));
  if (referenceDofs && s.adapt.referenceSteps == 0) SIGNORINI_INPUT_ERROR(comm, "option -adapt_reference_dofs: ends the reference steps early; give -adapt_reference_steps M too");
  // So would the options of a convergence study without one, and a study's own files are its table
  // (-study_output, -summary) and the profiles of its finest levels (-study_profiles), not -output.
  const bool study = s.study.levels > 0;
  for (const char *name : {"-study_output", "-study_spaces", "-study_profiles", "-reference_refine", "-reference_space"}) {
    PetscBool given;
    PetscCall(PetscOptionsHasName(NULL, NULL, name, &given));
    if (given && !study) SIGNORINI_INPUT_ERROR(comm, "option %s: applies to a convergence study only; give -study_levels L too", name);
  }
  if (study) {
    PetscBool space, spaces;
    if (!s.output.file.empty()) SIGNORINI_INPUT_ERROR(comm, "option -output: a convergence study writes the solutions of its finest level with -study_profiles PREFIX (one file per element)");
    PetscCall(PetscOptionsHasName(NULL, NULL, "-space", &space));
    PetscCall(PetscOptionsHasName(NULL, NULL, "-study_spaces", &spaces));
    if (space && spaces && s.study.elements != std::vector<Element>{s.element}) SIGNORINI_INPUT_ERROR(comm, "options -space and -study_spaces: a convergence study solves the elements of -study_spaces; give one of them");
    if (space) s.study.elements = {s.element};
    s.study.summary = s.summaryFile;
  }
  // Nested iteration needs the coarser levels of the refinement; a scene without contact is one linear solve.
  // An adaptive run solves its first mesh so too.
  const bool nestedLevels = s.nested.enabled && s.mesh.refine > 0 && s.nested.levels != 0 && s.study.levels == 0 && !s.problem.contact.empty();
  const bool nested       = nestedLevels && !adaptive;
  MeshLevels levels;
  // The scene is checked against the coarse mesh (dimension, boundary parts) before the refinement.
  // The sizes are checked against the coarse mesh before it is built (box) or distributed (file).
  PetscCall(MeshCreate(comm, s.mesh, &mesh, meshInfo, nestedLevels ? &levels : nullptr, s.nested.levels, [&](DM coarse) {
                         PetscInt cdim;
                         PetscFunctionBeginUser;
                         PetscCall(DMGetDimension(coarse, &cdim));
                         if (adaptive && s.adapt.refinement == LocalRefinement::SBR && cdim != 2) SIGNORINI_INPUT_ERROR(comm, "option -adapt_refinement: sbr refines triangles only; use bisection or bisection_all for tetrahedra");
                         PetscCall(ProblemCheckMesh(coarse, s.problem));
                         PetscFunctionReturn(0);
                       },
                       [&](const MeshCounts &coarse) { return CheckSizes(comm, s.mesh, coarse, s.element, s.study); }));
  PetscInt dim;
  PetscCall(DMGetDimension(mesh, &dim));
  // The contact solve's preconditioner for this mesh (stretched cells: BoomerAMG alone), chosen before a
  // strategy builds the multigrid's levels for it.
  if (s.problem.HasContact()) PetscCall(ChoosePreconditioner(mesh, s.solve.amgReuse, &report.aspect, &report.chosenForAspect));
  report.preconditioner = s.solve.amgReuse.innerType;
  if (s.study.levels > 0) {
    // A convergence study instead of a single run: the same scene on nested refinements of this mesh.
    PetscInt  N0 = s.mesh.file.empty() ? s.mesh.faces[0] << s.mesh.refine : 0;
    PetscReal h0;
    if (N0 > 0) h0 = (s.mesh.upper[0] - s.mesh.lower[0]) / N0;
    else PetscCall(MeshSize(mesh, &h0));
    s.study.nested = s.nested;
    ConvergenceStudy study(mesh, N0, h0, s.problem, s.assembly, s.solve, s.estimate, s.errorDegree, s.study);
    PetscCall(SolveMeshes(s.problem, study));
    PetscCall(study.Finish());
    PetscCall(DMDestroy(&mesh));
    PetscCall(WarnNotAppliedOptions(comm, s, nestedLevels));
    PetscFunctionReturn(0);
  }
  PipelineOptions po;
  po.element  = s.element;
  po.assembly = s.assembly;
  po.solve    = s.solve;
  po.estimate = s.estimate;
  po.withMesh = [&](const Space &space) {
    PetscFunctionBeginUser;
    if (!s.output.file.empty()) PetscCall(OutputBegin(space, s.output, output));
    // Nothing after this point needs the mesh (the output file has it now): free it before the assembly
    // and the solve need the memory (a tetrahedral mesh has about 25 points per P1 DOF).
    PetscCall(DMDestroy(&mesh));
    if (nested) PetscCall(DMDestroy(&levels.dm.back()));
    PetscFunctionReturn(0);
  };
  // One mesh, the refinement levels coarse to fine, or adaptively refined meshes, with each solution
  // carried to the next.
  MeshSolution fine;
  if (adaptive) {
    PipelineOptions ao = po;
    ao.withMesh        = nullptr; // the output is begun on the last mesh, known once solved
    ao.keepMesh        = !s.output.file.empty();
    AdaptOptions adapt = s.adapt;
    adapt.memoryCheck  = s.mesh.memoryCheck;
    adapt.memoryLimit  = s.mesh.memoryLimit;
    if (s.nested.solveTo == NestedOptions::Discretization) adapt.solveToFraction = s.nested.fraction;
    AdaptiveRefinement strategy(mesh, s.problem, ao, adapt, s.errorDegree);
    if (nestedLevels) strategy.StartNested(levels, s.nested);
    PetscCall(DMDestroy(&mesh)); // the strategy holds the mesh as long as it needs it
    PetscCall(SolveMeshes(s.problem, strategy));
    fine = std::move(strategy.finest);
    report.adapt          = strategy.rows;
    report.adaptEnded     = strategy.ended;
    report.adaptEndedText = strategy.endedText;
    meshInfo.cells        = strategy.rows[strategy.finestStep].cells;
    meshInfo.cellsPerRank = strategy.cellsPerRank;
    if (!s.output.file.empty()) PetscCall(OutputBegin(fine.space, s.output, output));
  } else if (nested) {
    NestedIteration strategy(levels, s.problem, po, s.nested);
    PetscCall(SolveMeshes(s.problem, strategy));
    fine = std::move(strategy.finest);
  } else {
    SingleRun strategy(mesh, po);
    PetscCall(SolveMeshes(s.problem, strategy));
    fine = std::move(strategy.finest);
  }
  Space &space = fine.space;
  Vec    u     = fine.u;
  PetscCall(MeshLevelsDestroy(levels));
  report.solve = fine.result;
  if (s.problem.HasExact()) PetscCall(ErrorAgainstExact(space, s.problem, fine.sys, u, s.errorDegree, report.error));

  report.scene         = s.problem.scene;
  report.element       = ElementName(s.element);
  report.mesh          = meshInfo.description;
  report.loadRule      = s.assembly.centroid ? "centroid" : Format("accurate (degree %d)", (int)s.assembly.loadDegree);
  report.dim           = dim;
  report.refine        = s.mesh.refine - s.mesh.coarsened; // as asked: the box's own refinements are in report.mesh
  report.coarseCells   = meshInfo.coarseCells;
  report.cells         = meshInfo.cells;
  report.cellsPerRank  = meshInfo.cellsPerRank;
  report.edgeCut       = meshInfo.edgeCut;
  report.boundary      = s.problem.coverage;
  report.dofs          = space.numGlobal;
  report.dirichletDofs = space.numDirichletGlobal;
  report.contactDofs   = space.numContactGlobal;
  report.ranks         = (PetscInt)meshInfo.cellsPerRank.size();
  report.hasExact      = s.problem.HasExact();
  ReportRecordExpressions(s.problem, report);
  if (!s.output.file.empty()) PetscCall(OutputEnd(space, s.problem, fine.sys, u, output, fine.estimate.cellEta2));
  report.estimate = std::move(fine.estimate);
  std::vector<PetscReal>().swap(report.estimate.cellEta2); // the report needs the sums only
  PetscCall(ReportGatherTimes(comm, start, report));
  PetscCall(ReportGatherMemory(comm, fine.sys.A, report));
  PetscCall(ReportPrint(comm, report));
  if (report.hasExact && report.estimate.computed && s.nested.solveTo != NestedOptions::Discretization) {
    // the smallest index of the run: the final mesh, or any adaptive step with its error
    PetscReal   eta = report.estimate.eta, error = report.error.energy;
    std::string where;
    for (size_t k = 0; k < report.adapt.size(); ++k) {
      const AdaptRow &a = report.adapt[k];
      if (a.error > 0 && a.eta / a.error < eta / error) eta = a.eta, error = a.error, where = Format(" at adaptive step %d", (int)k);
    }
    PetscCall(WarnBoundBelowError(comm, eta, error, report.error.exactEnergy, where));
  }
  if (!s.summaryFile.empty()) PetscCall(ReportWriteJSON(comm, report, s.summaryFile));

  PetscCall(fine.Destroy());
  PetscCall(DMDestroy(&mesh));
  PetscCall(WarnNotAppliedOptions(comm, s, nestedLevels));
  PetscFunctionReturn(0);
}

// A mistyped option must not pass unseen: list every option that no component read (as -options_left
// does), e.g. -snes_* options in a scene without a contact part, where no SNES is created.
static PetscErrorCode WarnUnusedOptions(MPI_Comm comm)
{
  PetscInt  n;
  char    **names, **values;
  PetscBool help, explicitLeft;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsHasHelp(NULL, &help));
  PetscCall(PetscOptionsHasName(NULL, NULL, "-options_left", &explicitLeft));
  if (help || explicitLeft) PetscFunctionReturn(0); // PETSc reports them itself with -options_left
  PetscCall(PetscOptionsLeftGet(NULL, &n, &names, &values));
  for (PetscInt i = 0; i < n; ++i) PetscCall(PetscPrintf(comm, "signorini: warning: option -%s%s%s was not used (mistyped, or not needed by this scene)\n", names[i], values[i] ? " " : "", values[i] ? values[i] : ""));
  PetscCall(PetscOptionsLeftRestore(NULL, &n, &names, &values));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  if (StartMPI(&argc, &argv, "signorini")) return 1; // a missing options file, in one line
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, help);
  if (ierr) return ierr;
  // Input errors get one line; -error_traceback restores PETSc's full traceback for debugging.
  PetscBool traceback = PETSC_FALSE;
  PetscOptionsGetBool(NULL, NULL, "-error_traceback", &traceback, NULL);
  if (!traceback) PetscPushErrorHandler(PetscReturnErrorHandler, NULL);
  ierr = Run(PETSC_COMM_WORLD);
  if (!ierr) ierr = WarnUnusedOptions(PETSC_COMM_WORLD);
  const int status = ExitStatus(PETSC_COMM_WORLD, ierr, "signorini");
  if (!traceback) PetscPopErrorHandler(); // -malloc_dump would list the pushed handler as a leak
  PetscFinalize();
  MPI_Finalize(); // StartMPI began MPI, so PetscFinalize leaves it running
  return status;
}
