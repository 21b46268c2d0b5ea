"""A mistyped option never passes unseen. An unknown application option is an error before the run (see
test_input_numbers); an option of a PETSc family that nothing read (-snes_monitr, or -snes_rtol in a scene
without contact, where no SNES is created) is listed at the end of the run; a run with only valid options
lists none."""
from harness import Checker, run, scene

c = Checker()
base = scene("paper-5.1") + ["-box_faces", "8"]
for ranks in [1, 2]:
    _, out, _, _ = run(base + ["-snes_monitr", "-ksp_monitr", "2"], ranks=ranks)
    warned = [l for l in out.splitlines() if l.startswith("signorini: warning: option")]
    c.check(len(warned) == 2 and "-snes_monitr" in warned[0] + warned[1] and "-ksp_monitr 2" in warned[0] + warned[1],
            "%d rank(s): mistyped PETSc options listed once each: %s" % (ranks, warned))
_, out, _, _ = run(base + ["-snes_monitor", "-ksp_converged_reason"])
c.check("warning" not in out, "valid options: no warning")
_, out, _, _ = run(base + ["-bc_contact", "", "-snes_rtol", "1e-9"])
c.check("option -snes_rtol 1e-9 was not used" in out, "no contact part: the SNES option is reported unused")
c.done()
