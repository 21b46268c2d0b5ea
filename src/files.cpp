#include "signorini/files.h"

#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>

namespace signorini {

// ---- Temporary names the signal handler removes. The handler may only call async-signal-safe functions,
// so the names live in fixed buffers, and a slot is published (used = 1) only after its name is complete.
namespace {
constexpr int         kSlots = 32;
char                  slotPath[kSlots][PATH_MAX];
volatile sig_atomic_t slotUsed[kSlots];
const int             kSignals[] = {SIGINT, SIGTERM, SIGHUP};
struct sigaction      previous[sizeof kSignals / sizeof kSignals[0]];
bool                  installed = false;

extern "C" void RemoveTemporariesOnSignal(int sig, siginfo_t *info, void *context)
{
  const int saved = errno;
  for (int i = 0; i < kSlots; ++i)
    if (slotUsed[i]) unlink(slotPath[i]);
  errno = saved;
  for (size_t k = 0; k < sizeof kSignals / sizeof kSignals[0]; ++k) {
    if (kSignals[k] != sig) continue;
    const struct sigaction &p = previous[k];
    if (p.sa_flags & SA_SIGINFO) return p.sa_sigaction(sig, info, context);
    if (p.sa_handler != SIG_DFL && p.sa_handler != SIG_IGN) return p.sa_handler(sig); // PETSc's (SIGHUP)
  }
  // The default action: the process ends as the signal would have ended it (status 128 + sig in a shell).
  signal(sig, SIG_DFL);
  raise(sig); // delivered when the handler returns and the signal is unblocked
}

// Installed at the first temporary file, which is after PetscInitialize (PETSc installs its handlers there;
// with Open MPI it leaves SIGINT and SIGTERM alone and handles SIGHUP, which is chained). A signal the
// process ignores (nohup) stays ignored.
void InstallHandler()
{
  if (installed) return;
  installed = true;
  struct sigaction a;
  std::memset(&a, 0, sizeof a);
  a.sa_sigaction = RemoveTemporariesOnSignal;
  a.sa_flags     = SA_SIGINFO | SA_RESTART;
  sigemptyset(&a.sa_mask);
  for (int s : kSignals) sigaddset(&a.sa_mask, s); // one handler at a time
  for (size_t k = 0; k < sizeof kSignals / sizeof kSignals[0]; ++k) {
    if (sigaction(kSignals[k], nullptr, &previous[k]) != 0) continue;
    if (!(previous[k].sa_flags & SA_SIGINFO) && previous[k].sa_handler == SIG_IGN) continue;
    sigaction(kSignals[k], &a, nullptr);
  }
}

int Register(const std::string &path)
{
  InstallHandler();
  if (path.empty() || path.size() >= PATH_MAX) return -1;
  for (int i = 0; i < kSlots; ++i)
    if (!slotUsed[i]) {
      std::memcpy(slotPath[i], path.c_str(), path.size() + 1);
      std::atomic_signal_fence(std::memory_order_seq_cst);
      slotUsed[i] = 1;
      return i;
    }
  return -1; // more temporaries than slots at once: this one is removed on errors, not on signals
}

void Unregister(int slot)
{
  if (slot >= 0) slotUsed[slot] = 0;
}

std::string DirName(const std::string &path)
{
  const size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

std::string BaseName(const std::string &path)
{
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

// The file that writing `path` changes: symbolic links in the last component are followed (a link that
// points to nothing yet gives the path it points to), and the directory is made absolute and free of
// links, so that two names of one file compare equal. Rank 0 only. Returns the reason on failure.
std::string Resolve(const std::string &path, std::string &file, bool *followed = nullptr)
{
  std::string p = path;
  if (followed) *followed = false;
  for (int hops = 0;; ++hops) {
    struct stat st;
    if (lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) break;
    char    target[PATH_MAX];
    ssize_t n = readlink(p.c_str(), target, sizeof target - 1);
    if (hops == 40 || n < 0) return "is a symbolic link that cannot be followed";
    target[n] = '\0';
    p         = target[0] == '/' ? std::string(target) : DirName(p) + "/" + target;
    if (followed) *followed = true;
  }
  char dir[PATH_MAX];
  if (!realpath(DirName(p).c_str(), dir)) return Format("cannot be written: its directory '%s' %s", DirName(p).c_str(), errno == ENOENT ? "does not exist" : std::strerror(errno));
  file = std::string(dir) + (dir[1] ? "/" : "") + BaseName(p);
  return "";
}

// The mode a new file gets from open(2) (0666 less the umask), or the mode of the file it replaces.
mode_t ModeFor(const std::string &file, uid_t *uid, gid_t *gid)
{
  struct stat st;
  if (stat(file.c_str(), &st) == 0) {
    *uid = st.st_uid, *gid = st.st_gid;
    return st.st_mode & 07777;
  }
  *uid = (uid_t)-1, *gid = (gid_t)-1;
  const mode_t mask = umask(0);
  umask(mask);
  return 0666 & ~mask;
}

// Creates FILE.tmp-XXXXXX exclusively (so it can be neither another run's nor a user's file) with the
// mode and owner that `file` has or would get. Returns the open descriptor, or -1 with errno set.
int CreateTemporary(const std::string &file, std::string &name)
{
  std::string templ = file + ".tmp-XXXXXX";
  int         fd    = mkstemp(&templ[0]);
  if (fd < 0) return -1;
  uid_t        uid;
  gid_t        gid;
  const mode_t mode = ModeFor(file, &uid, &gid);
  if (fchmod(fd, mode) != 0 || (uid != (uid_t)-1 && fchown(fd, uid, gid) != 0 && geteuid() == 0)) {
    const int e = errno;
    close(fd);
    unlink(templ.c_str());
    errno = e;
    return -1;
  }
  name = templ;
  return fd;
}

// Why `path` may not be written, or "" (rank 0). `file` is the resolved file.
std::string WhyNotWritable(const std::string &path, std::string &file)
{
  bool        link;
  std::string why = Resolve(path, file, &link);
  if (!why.empty()) return why;
  const std::string through = link ? Format(" (the symbolic link leads to '%s')", file.c_str()) : "";
  struct stat       st;
  if (stat(file.c_str(), &st) == 0) {
    if (S_ISDIR(st.st_mode)) return "is a directory, not a file" + through;
    if (!S_ISREG(st.st_mode)) return "is not a regular file (a device, pipe or socket), which the output must not replace" + through;
    // root may write anything, so the mode bits are checked too: a read-only file is the user's decision
    if (!(st.st_mode & 0222) || access(file.c_str(), W_OK) != 0) return "is a read-only file" + through;
  } else if (errno != ENOENT) return Format("cannot be written (%s)", std::strerror(errno)) + through;
  std::string tmp;
  const int   fd = CreateTemporary(file, tmp);
  if (fd < 0) return Format("cannot be written: no file can be created in its directory (%s)", std::strerror(errno)) + through;
  close(fd);
  unlink(tmp.c_str());
  return "";
}

PetscErrorCode BcastString(MPI_Comm comm, std::string &s)
{
  int n = (int)s.size();
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Bcast(&n, 1, MPI_INT, 0, comm));
  s.resize(n);
  PetscCallMPI(MPI_Bcast(&s[0], n, MPI_CHAR, 0, comm));
  PetscFunctionReturn(0);
}

struct Claim {
  std::string option, path, file;
};
std::vector<Claim> claims; // identical on every rank (the options database is)
} // namespace

PetscErrorCode FileClaim(MPI_Comm comm, const std::string &option, const std::string &path)
{
  PetscMPIInt rank;
  std::string why, file;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  if (rank == 0) why = WhyNotWritable(path, file);
  PetscCall(CheckAll(comm, why.empty(), Format("option %s: '%s' %s", option.c_str(), path.c_str(), why.c_str())));
  PetscCall(BcastString(comm, file));
  for (const Claim &c : claims)
    if (c.file == file) {
      if (c.option == option) SIGNORINI_INPUT_ERROR(comm, "option %s: '%s' and '%s' are the same file, which the run would write twice", option.c_str(), c.path.c_str(), path.c_str());
      if (c.path == path) SIGNORINI_INPUT_ERROR(comm, "options %s and %s: both write to '%s'", c.option.c_str(), option.c_str(), path.c_str());
      SIGNORINI_INPUT_ERROR(comm, "options %s and %s: '%s' and '%s' are the same file, which both would write", c.option.c_str(), option.c_str(), c.path.c_str(), path.c_str());
    }
  claims.push_back({option, path, file});
  PetscFunctionReturn(0);
}

PetscErrorCode FileSet::Add(MPI_Comm comm, const std::string &target, std::string &temporary)
{
  std::string why, file;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank_));
  temporary.clear();
  if (rank_ == 0) {
    why = Resolve(target, file);
    if (why.empty()) {
      const int fd = CreateTemporary(file, temporary);
      if (fd < 0) why = Format("cannot be written (%s)", std::strerror(errno));
      else close(fd);
    }
  }
  PetscCall(CheckAll(comm, why.empty(), Format("output file '%s' %s", target.c_str(), why.c_str())));
  PetscCall(BcastString(comm, file));
  PetscCall(BcastString(comm, temporary));
  // every rank registers the name, so that a signal to any of them removes it
  entries_.push_back({file, temporary, Register(temporary)});
  PetscFunctionReturn(0);
}

PetscErrorCode FileSet::AddText(MPI_Comm comm, const std::string &target, const std::string &text)
{
  std::string tmp, problem;
  PetscFunctionBeginUser;
  PetscCall(Add(comm, target, tmp));
  if (rank_ == 0) {
    FILE *fp = std::fopen(tmp.c_str(), "w");
    bool  ok = fp && std::fwrite(text.data(), 1, text.size(), fp) == text.size();
    if (fp) ok = (std::fclose(fp) == 0) && ok;
    if (!ok) problem = Format("output file '%s': writing failed (%s)", target.c_str(), std::strerror(errno));
  }
  PetscCall(CheckAll(comm, problem.empty(), problem));
  PetscFunctionReturn(0);
}

// A new name for a hard link to `file`, so that its content survives a rename over it ("" if none).
static std::string KeepOldContent(const std::string &file)
{
  struct stat st;
  if (stat(file.c_str(), &st) != 0) return "";
  for (int attempt = 0; attempt < 8; ++attempt) {
    std::string name;
    const int   fd = CreateTemporary(file, name); // reserves a unique name ...
    if (fd < 0) return "";
    close(fd);
    unlink(name.c_str());
    if (link(file.c_str(), name.c_str()) == 0) return name; // ... unless another process took it meanwhile
  }
  return "";
}

PetscErrorCode FileSet::Commit(MPI_Comm comm)
{
  std::string problem;
  PetscFunctionBeginUser;
  if (rank_ == 0) {
    const size_t             n = entries_.size();
    std::vector<std::string> kept(n);
    std::vector<int>         keptSlot(n, -1);
    std::vector<bool>        existed(n);
    for (size_t i = 0; i < n; ++i) {
      struct stat st;
      existed[i] = stat(entries_[i].target.c_str(), &st) == 0;
      if (n > 1 && existed[i]) keptSlot[i] = Register(kept[i] = KeepOldContent(entries_[i].target));
    }
    size_t done = 0;
    for (; done < n; ++done)
      if (std::rename(entries_[done].temporary.c_str(), entries_[done].target.c_str()) != 0) {
        problem = Format("output file '%s': cannot be written (%s); no output file of this step was changed", entries_[done].target.c_str(), std::strerror(errno));
        break;
      }
    for (size_t i = 0; i < n; ++i) {
      if (done < n && i < done) { // undo
        if (!kept[i].empty()) std::rename(kept[i].c_str(), entries_[i].target.c_str());
        else if (!existed[i]) unlink(entries_[i].target.c_str());
      }
      if (!kept[i].empty()) unlink(kept[i].c_str());
      Unregister(keptSlot[i]);
    }
  }
  if (problem.empty()) {
    for (Entry &e : entries_) Unregister(e.slot);
    entries_.clear();
  }
  PetscCall(CheckAll(comm, problem.empty(), problem)); // the destructor removes what is left
  PetscFunctionReturn(0);
}

void FileSet::Discard()
{
  for (Entry &e : entries_) {
    if (rank_ == 0) unlink(e.temporary.c_str());
    Unregister(e.slot);
  }
  entries_.clear();
}

PetscErrorCode WriteFileAtomically(MPI_Comm comm, const std::string &file, const std::string &text)
{
  FileSet set;
  PetscFunctionBeginUser;
  PetscCall(set.AddText(comm, file, text));
  PetscCall(set.Commit(comm));
  PetscFunctionReturn(0);
}

} // namespace signorini
