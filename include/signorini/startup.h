// Starting an executable. PetscInitialize reads the options files, and one that cannot be opened ends it
// with PETSc's traceback on rank 0 while the other ranks wait in a broadcast; so the files are checked
// first, where a missing one can still be reported in one line on every number of ranks.
#pragma once

namespace signorini {

// Initializes MPI (the caller calls MPI_Finalize after PetscFinalize) and checks on rank 0 that every file
// that PetscInitialize will read as required, the files of -options_file and -options_file_yaml on the
// command line, in PETSC_OPTIONS, and in such files themselves, can be opened. Returns 0, or 1 after
// printing one line "PROGRAM: error: ..." on rank 0 and finalizing MPI. Names that PETSc expands ('~',
// '$VARIABLE') are left to PETSc. Sets SCOTCH_PTHREAD_NUMBER=1 where the environment does not set it, so that
// PT-Scotch's partitions, and the results that depend on them, are the same in every run.
int StartMPI(int *argc, char ***argv, const char *program);

} // namespace signorini
