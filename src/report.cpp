#include "signorini/report.h"
#include "signorini/options.h"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace signorini {

PetscErrorCode ReportOptionsFromCommandLine(MPI_Comm comm, std::string &summaryFile)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Summary", "signorini");
  PetscCall(OptionString(PetscOptionsObject, "-summary", "Write the run's figures as JSON to this file", summaryFile));
  PetscOptionsEnd();
  if (!summaryFile.empty()) PetscCall(FileClaim(comm, "-summary", summaryFile));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportGatherTimes(MPI_Comm comm, PetscLogDouble start, Report &r)
{
  PetscLogDouble now;
  PetscFunctionBeginUser;
  PetscCall(PetscTime(&now));
  PetscLogDouble t[(int)Stage::Count + 1];
  for (int s = 0; s < (int)Stage::Count; ++s) t[s] = StageSeconds((Stage)s);
  t[(int)Stage::Count] = now - start;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, t, (int)Stage::Count + 1, MPI_DOUBLE, MPI_MAX, comm));
  for (int s = 0; s < (int)Stage::Count; ++s) r.stageSeconds[s] = t[s];
  r.totalSeconds = t[(int)Stage::Count];
  PetscFunctionReturn(0);
}

PetscErrorCode PeakRSS(MPI_Comm comm, double *sum, double *max)
{
  struct rusage ru;
  PetscFunctionBeginUser;
  PetscCheck(getrusage(RUSAGE_SELF, &ru) == 0, PETSC_COMM_SELF, PETSC_ERR_SYS, "getrusage failed");
  const double mine = 1024.0 * ru.ru_maxrss; // kilobytes on Linux
  PetscCallMPI(MPI_Allreduce(&mine, sum, 1, MPI_DOUBLE, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(&mine, max, 1, MPI_DOUBLE, MPI_MAX, comm));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportGatherMemory(MPI_Comm comm, Mat A, Report &r)
{
  MatInfo   info;
  PetscInt  rows;
  PetscBool mpi, tracing;
  PetscFunctionBeginUser;
  PetscCall(PeakRSS(comm, &r.peakRSSSum, &r.peakRSSMax));
  // MatInfo.memory is always 0 in PETSc 3.18, so the AIJ storage is counted from the nonzeros: a value and a
  // column index each, and four index arrays of the rows (offsets, lengths, allocated lengths, diagonal) per
  // block (MPIAIJ keeps a diagonal and an off-diagonal block).
  PetscCall(MatGetInfo(A, MAT_GLOBAL_SUM, &info));
  PetscCall(MatGetSize(A, &rows, NULL));
  PetscCall(PetscObjectTypeCompare((PetscObject)A, MATMPIAIJ, &mpi));
  r.matrixBytes = info.nz_allocated * (sizeof(PetscScalar) + sizeof(PetscInt)) + (mpi ? 2 : 1) * 4.0 * sizeof(PetscInt) * rows;
  // PETSc counts its mallocs only with its tracing allocator, which must be chosen before PetscInitialize.
  PetscCall(PetscMallocGetDebug(&tracing, NULL, NULL));
  r.petscMallocPeak = -1;
  if (tracing) {
    PetscLogDouble mine;
    PetscCall(PetscMallocGetMaximumUsage(&mine));
    PetscCallMPI(MPI_Allreduce(&mine, &r.petscMallocPeak, 1, MPI_DOUBLE, MPI_SUM, comm));
  }
  PetscFunctionReturn(0);
}

static std::string Bytes(double b)
{
  return b >= 1e9 ? Format("%.2f GB", b / 1e9) : Format("%.1f MB", b / 1e6);
}

PetscErrorCode WarnBoundBelowError(MPI_Comm comm, PetscReal eta, PetscReal error, PetscReal norm, const std::string &where)
{
  PetscFunctionBeginUser;
  if (!(eta < error) || error <= 1e-6 * norm) PetscFunctionReturn(0);
  PetscCall(PetscPrintf(comm, "signorini: warning: the estimate eta %.6e is below the energy error %.6e against -exact_u%s (index %.3f), although it bounds that error where -exact_u and -exact_grad solve this scene, u_D and psi are affine on each boundary face, the load rule is exact and the solve converged: check -exact_u and -exact_grad against the data\n", (double)eta, (double)error, where.c_str(), (double)(eta / error)));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportPrint(MPI_Comm comm, const Report &r)
{
  std::ostringstream o;
  PetscFunctionBeginUser;
  o << Format("scene %s: element %s, %dD, mesh %s, refine %d: %d cells, %d DOFs (%d Dirichlet, %d contact), %d rank(s)\n", r.scene.c_str(), r.element.c_str(), (int)r.dim, r.mesh.c_str(), (int)r.refine, (int)r.cells, (int)r.dofs, (int)r.dirichletDofs, (int)r.contactDofs, (int)r.ranks);
  if (r.solve.vi) {
    o << Format("  solve: SNESVI %s, %d Newton / %d KSP iterations", r.solve.reason.c_str(), (int)r.solve.newtonIts, (int)r.solve.kspIts);
    if (r.solve.kktSteps > 0) o << Format(" (%d of them after the residual test passed, for the KKT checks)", (int)r.solve.kktSteps);
    o << "\n";
    if (r.chosenForAspect) o << Format("  preconditioner of the inactive-set blocks: BoomerAMG alone, for cells stretched up to aspect ratio %.3g (the geometric multigrid's smoother does not smooth across them; -vi_pc_type mg keeps it)\n", (double)r.aspect);
    if (r.solve.amg.setups + r.solve.amg.reuses > 0) o << Format("  preconditioner of the inactive-set blocks (%s) set up %d times, re-used in %d Newton steps\n", r.preconditioner.c_str(), (int)r.solve.amg.setups, (int)r.solve.amg.reuses);
    if (!r.solve.levels.empty()) o << Format("  nested iteration, -solve_to %s\n", r.solve.stopping.c_str());
    for (size_t l = 0; l < r.solve.levels.size(); ++l) {
      const SolveResult::Level &v = r.solve.levels[l];
      o << Format("  nested level %d: %d DOFs, %d Newton / %d KSP iterations, set-up %.3f s, solve %.3f s, stopped by %s\n", (int)l, (int)v.dofs, (int)v.newtonIts, (int)v.kspIts, v.setupSeconds, v.solveSeconds, v.stoppedBy.c_str());
    }
    if (r.contactDofs == 0) o << "  KKT on Gamma_C: nothing to check (no contact DOFs: those of Gamma_C all lie on Gamma_D)\n";
    else o << Format("  KKT on Gamma_C: min(u-psi) %.3e, min pressure %.3e, max |(u-psi) pressure| %.3e (worst relative %.1e), active %d of %d\n", (double)r.solve.primal, (double)r.solve.dual, (double)r.solve.complementarity, (double)r.solve.kktRelative, (int)r.solve.active, (int)r.contactDofs);
  } else {
    o << Format("  solve: KSP %s, %d iterations (no contact part: linear solve", r.solve.reason.c_str(), (int)r.solve.kspIts);
    if (r.solve.kktSteps > 0) o << Format("; %d more solve%s from where it stopped, for the stationarity check", (int)r.solve.kktSteps, r.solve.kktSteps > 1 ? "s" : "");
    o << ")\n";
  }
  if (r.solve.linearSeconds >= 0) o << Format("  solve %.3f s, one linear CG + BoomerAMG solve of the same A, b %.3f s (%d iterations): ratio %.2f\n", r.solve.solveSeconds, r.solve.linearSeconds, (int)r.solve.linearKspIts, r.solve.solveSeconds / r.solve.linearSeconds);
  o << Format("  stationarity max|r| / max|load| on free DOFs %.3e, energy J(u_h) = %.12e\n", (double)r.solve.stationarity, (double)r.solve.energy);
  if (!r.adapt.empty()) o << AdaptTable(r.adapt);
  if (!r.adaptEndedText.empty()) o << "  adaptive refinement " << r.adaptEndedText << "\n";
  if (r.hasExact) o << Format("  error vs exact: L2 %.6e, broken H1 seminorm %.6e, H1 %.6e, energy %.6e\n", (double)r.error.l2, (double)r.error.h1semi, (double)r.error.h1, (double)r.error.energy);
  if (r.estimate.computed) {
    const Estimate &e = r.estimate;
    // The contact term gamma = int_{Gamma_C} sigma.n (v - psi) is of the units of eta^2 (E^2 <= (F + osc) E + gamma):
    // printed beside the norms as sqrt(gamma), where it scales like them (the summary keeps gamma).
    o << Format("  estimate of the energy error: eta %.6e (flux %.3e, nonconformity %.3e, contact sqrt(gamma) %.3e, oscillation %.3e), %.3f s\n", (double)e.eta, (double)e.flux, (double)e.nonconformity, (double)std::sqrt(std::max(e.contact, (PetscReal)0)), (double)e.oscillation, e.seconds);
    if (r.hasExact) o << Format("  energy error %.6e, estimate %.6e, efficiency index eta/error %.3f\n", (double)r.error.energy, (double)e.eta, (double)(e.eta / r.error.energy));
  }
  o << "  time [s]:";
  for (int s = 0; s < (int)Stage::Count; ++s) o << Format(" %s %.3f", StageName((Stage)s), r.stageSeconds[s]);
  o << Format(", total %.3f\n", r.totalSeconds);
  if (r.peakRSSSum > 0) {
    const double dofs = (double)std::max(r.dofs, (PetscInt)1);
    o << Format("  memory: peak RSS %s (sum over ranks, max rank %s), %.0f B/DOF; matrix %s, %.0f B/DOF; ", Bytes(r.peakRSSSum).c_str(), Bytes(r.peakRSSMax).c_str(), r.peakRSSSum / dofs, Bytes(r.matrixBytes).c_str(), r.matrixBytes / dofs);
    if (r.petscMallocPeak >= 0) o << Format("PETSc malloc peak %s, %.0f B/DOF\n", Bytes(r.petscMallocPeak).c_str(), r.petscMallocPeak / dofs);
    else o << "PETSc malloc peak not traced (-malloc_dump traces it)\n";
  }
  PetscCall(PetscPrintf(comm, "%s", o.str().c_str()));
  PetscFunctionReturn(0);
}

static std::string Num(double v) { return std::isfinite(v) ? Format("%.17g", v) : "null"; }
static std::string Str(const std::string &s)
{
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if ((unsigned char)c < 0x20) out += Format("\\u%04x", (unsigned)c); // a newline in an argument
    else out += c;
  }
  return out + "\"";
}

std::string EstimateJSON(const Estimate &e, const ErrorNorms *error)
{
  std::string o = "{\"eta\": " + Num(e.eta) + ", \"flux\": " + Num(e.flux) + ", \"nonconformity\": " + Num(e.nonconformity) + ", \"contact\": " + Num(e.contact) + ", \"oscillation\": " + Num(e.oscillation) + ", \"seconds\": " + Num(e.seconds);
  if (error) o += ", \"efficiency\": " + Num(e.eta / error->energy);
  return o + "}";
}

void ReportRecordExpressions(const Problem &p, Report &r)
{
  r.expressions.clear();
  for (const Expression *e : {p.f.get(), p.g.get(), p.uD.get(), p.psi.get(), p.kappa.get(), p.exact.get()})
    if (e) r.expressions.emplace_back(e->Option().substr(1), e->Text());
  if (p.exact) r.expressions.emplace_back("exact_grad", p.exactGradText);
}

// The command line as the program got it, as a JSON list.
static std::string CommandLine()
{
  int    argc = 0;
  char **argv = nullptr;
  PetscGetArgs(&argc, &argv);
  std::string out = "[";
  for (int i = 0; i < argc; ++i) out += (i ? ", " : "") + Str(argv[i]);
  return out + "]";
}

PetscErrorCode ReportWriteJSON(MPI_Comm comm, const Report &r, const std::string &file)
{
  std::ostringstream o;
  PetscFunctionBeginUser;
  o << "{\n";
  o << "  \"command_line\": " << CommandLine() << ",\n  \"expressions\": {";
  for (size_t i = 0; i < r.expressions.size(); ++i) o << (i ? ", " : "") << Str(r.expressions[i].first) << ": " << Str(r.expressions[i].second);
  o << "},\n";
  o << "  \"scene\": " << Str(r.scene) << ",\n  \"element\": " << Str(r.element) << ",\n  \"dim\": " << r.dim << ",\n";
  o << "  \"mesh\": " << Str(r.mesh) << ",\n  \"refine\": " << r.refine << ",\n  \"coarse_cells\": " << r.coarseCells << ",\n  \"cells\": " << r.cells << ",\n";
  o << "  \"dofs\": " << r.dofs << ",\n  \"dirichlet_dofs\": " << r.dirichletDofs << ",\n  \"contact_dofs\": " << r.contactDofs << ",\n";
  o << "  \"ranks\": " << r.ranks << ",\n  \"edge_cut\": " << r.edgeCut << ",\n  \"cells_per_rank\": [";
  for (size_t i = 0; i < r.cellsPerRank.size(); ++i) o << (i ? ", " : "") << r.cellsPerRank[i];
  o << "],\n  \"boundary_faces_coarse\": " << r.boundary.faces << ",\n  \"unnamed_boundary_faces_coarse\": " << r.boundary.unnamed << ",\n  \"pieces_coarse\": " << r.boundary.pieces;
  if (r.boundary.exactFailed >= 0) o << ",\n  \"exact_failed_checks\": " << r.boundary.exactFailed;
  o << ",\n  \"load_quadrature\": " << Str(r.loadRule) << ",\n";
  o << "  \"solver\": {\"type\": " << Str(r.solve.vi ? "snesvi" : "ksp") << ", \"converged_reason\": " << Str(r.solve.reason) << ", \"newton_iterations\": " << r.solve.newtonIts << ", \"ksp_iterations\": " << r.solve.kspIts;
  o << ", \"kkt_steps\": " << r.solve.kktSteps << ", \"solve_seconds\": " << Num(r.solve.solveSeconds) << ", \"nested\": " << (r.solve.levels.empty() ? "false" : "true");
  if (r.solve.vi) o << ", \"amg_setups\": " << r.solve.amg.setups << ", \"amg_reuses\": " << r.solve.amg.reuses << ", \"preconditioner\": " << Str(r.preconditioner) << ", \"max_aspect_ratio\": " << Num(r.aspect);
  if (!r.solve.levels.empty()) {
    PetscInt newton = 0, ksp = 0;
    o << ", \"levels\": [";
    for (size_t l = 0; l < r.solve.levels.size(); ++l) {
      const SolveResult::Level &v = r.solve.levels[l];
      newton += v.newtonIts, ksp += v.kspIts;
      o << (l ? ", " : "") << "{\"dofs\": " << v.dofs << ", \"newton\": " << v.newtonIts << ", \"ksp\": " << v.kspIts << ", \"amg_setups\": " << v.amgSetups << ", \"setup_seconds\": " << Num(v.setupSeconds) << ", \"seconds\": " << Num(v.solveSeconds) << ", \"stopped_by\": " << Str(v.stoppedBy) << ", \"energy_error_target\": " << Num(v.energyError) << "}";
    }
    o << "], \"newton_iterations_total\": " << newton << ", \"ksp_iterations_total\": " << ksp << ", \"solve_to\": " << Str(r.solve.stopping);
  }
  if (r.solve.linearSeconds >= 0) o << ", \"linear_solve_seconds\": " << Num(r.solve.linearSeconds) << ", \"linear_ksp_iterations\": " << r.solve.linearKspIts << ", \"solve_linear_ratio\": " << Num(r.solve.solveSeconds / r.solve.linearSeconds);
  o << "},\n";
  if (r.solve.vi) { // without contact DOFs (Gamma_C all on Gamma_D) the minima and maxima are of nothing: null
    const auto kkt = [&](double v) { return r.contactDofs > 0 ? Num(v) : std::string("null"); };
    o << "  \"kkt\": {\"min_gap\": " << kkt(r.solve.primal) << ", \"min_pressure\": " << kkt(r.solve.dual) << ", \"max_complementarity\": " << kkt(r.solve.complementarity) << ", \"max_pressure\": " << kkt(r.solve.pressureMax) << ", \"max_gap\": " << kkt(r.solve.gapMax) << ", \"relative\": " << kkt(r.solve.kktRelative) << ", \"active\": " << r.solve.active << "},\n";
  }
  o << "  \"stationarity\": " << Num(r.solve.stationarity) << ",\n  \"energy\": " << Num(r.solve.energy) << ",\n";
  if (!r.adapt.empty()) {
    o << "  \"adapt\": [";
    for (size_t k = 0; k < r.adapt.size(); ++k) {
      const AdaptRow &a = r.adapt[k];
      o << (k ? ",\n    " : "\n    ") << "{\"cells\": " << a.cells << ", \"dofs\": " << a.dofs << ", \"eta\": " << Num(a.eta) << ", \"error\": " << (a.error >= 0 ? Num(a.error) : "null");
      o << ", \"error_reference\": " << (a.referenceError >= 0 ? Num(a.referenceError) : "null") << ", \"reference_step\": " << (a.reference ? "true" : "false");
      o << ", \"newton\": " << a.newtonIts << ", \"ksp\": " << a.kspIts << ", \"nested_levels\": " << a.nestedLevels << ", \"marked\": " << a.marked << ", \"redistributed\": " << (a.redistributed ? "true" : "false");
      o << ", \"run_seconds\": " << Num(a.runSeconds) << ", \"setup_seconds\": " << Num(a.setupSeconds) << ", \"solve_seconds\": " << Num(a.solveSeconds) << ", \"estimate_seconds\": " << Num(a.estimateSeconds) << ", \"mark_seconds\": " << Num(a.markSeconds) << ", \"refine_seconds\": " << Num(a.refineSeconds);
      o << ", \"redistribute_seconds\": " << Num(a.redistributeSeconds) << ", \"transfer_seconds\": " << Num(a.transferSeconds) << "}";
    }
    o << "\n  ],\n  \"adapt_ended\": \"" << r.adaptEnded << "\",\n";
  }
  if (r.hasExact) o << "  \"error\": {\"l2\": " << Num(r.error.l2) << ", \"h1_semi\": " << Num(r.error.h1semi) << ", \"h1\": " << Num(r.error.h1) << ", \"energy\": " << Num(r.error.energy) << "},\n";
  if (r.estimate.computed) o << "  \"estimate\": " << EstimateJSON(r.estimate, r.hasExact ? &r.error : nullptr) << ",\n";
  o << "  \"time\": {";
  for (int s = 0; s < (int)Stage::Count; ++s) o << Str(StageName((Stage)s)) << ": " << Num(r.stageSeconds[s]) << ", ";
  o << "\"total\": " << Num(r.totalSeconds) << "},\n";
  o << "  \"memory\": {\"peak_rss_bytes_sum\": " << Num(r.peakRSSSum) << ", \"peak_rss_bytes_max\": " << Num(r.peakRSSMax) << ", \"peak_rss_bytes_per_dof\": " << Num(r.peakRSSSum / std::max(r.dofs, (PetscInt)1));
  o << ", \"matrix_bytes\": " << Num(r.matrixBytes) << ", \"petsc_malloc_peak_bytes\": " << (r.petscMallocPeak >= 0 ? Num(r.petscMallocPeak) : "null") << "}\n}\n";
  PetscCall(WriteFileAtomically(comm, file, o.str()));
  PetscFunctionReturn(0);
}

} // namespace signorini
