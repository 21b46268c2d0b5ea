// Every file the program writes goes through this component, so that writing output never harms a file:
//  - at options time, before any work, FileClaim checks each target: it does not exist, or it is a regular
//    file that may be written; its directory takes new files; and no other output of the same run resolves
//    to the same file. A symbolic link is followed: the file it points to gets the content, the link stays.
//  - at write time a FileSet gives each target a temporary name in the target's directory that no other run
//    and no user's file can have (NAME.tmp-XXXXXX, created exclusively on rank 0), and Commit renames the
//    temporaries onto their targets, all or none: files of one set (the HDF5 file and its XDMF files)
//    appear together or not at all, and a run that fails or is interrupted leaves the old files as they were.
//  - a temporary is removed when its set is destroyed uncommitted (any error) and when the process gets
//    SIGINT, SIGTERM or SIGHUP (also when mpirun forwards them): a handler unlinks the registered names and
//    lets the signal end the process as it would have (PETSc's own handler, where it has one, runs after).
#pragma once

#include "signorini/common.h"

namespace signorini {

// Collective, at options time: checks that `path`, named by `option`, may be written (see above); an
// input error naming the option and the path otherwise. The claims of a run are remembered, so that two
// options writing to the same file are refused.
PetscErrorCode FileClaim(MPI_Comm comm, const std::string &option, const std::string &path);

// Files written together; see above. Collective methods are called on every rank of comm.
class FileSet {
public:
  FileSet() = default;
  FileSet(const FileSet &)            = delete;
  FileSet &operator=(const FileSet &) = delete;
  ~FileSet() { Discard(); }
  // Collective: creates an empty temporary file for `target` and returns its name on every rank.
  PetscErrorCode Add(MPI_Comm comm, const std::string &target, std::string &temporary);
  // Collective: a temporary for `target` holding `text` (written by rank 0).
  PetscErrorCode AddText(MPI_Comm comm, const std::string &target, const std::string &text);
  // Collective: renames every temporary onto its target. If one rename fails, the targets already replaced
  // get their previous content back (kept as a hard link until the end), and the error names the file.
  PetscErrorCode Commit(MPI_Comm comm);
  // Removes the temporaries not yet committed (rank 0); nothing to do after Commit.
  void Discard();

private:
  struct Entry {
    std::string target, temporary;
    int         slot; // in the signal handler's list, -1 if none
  };
  std::vector<Entry> entries_;
  PetscMPIInt        rank_ = 0;
};

// Collective: writes `text` (from rank 0) to `file` through a FileSet of one file.
PetscErrorCode WriteFileAtomically(MPI_Comm comm, const std::string &file, const std::string &text);

} // namespace signorini
