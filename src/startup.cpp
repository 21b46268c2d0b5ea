#include "signorini/startup.h"
#include "signorini/common.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <strings.h>

namespace signorini {

namespace {

const int kMaxDepth = 16; // options files including each other in a cycle are PETSc's to report

std::string CheckFiles(const std::vector<std::string> &tokens, const std::string &where, int depth);

// The options of an options file as PETSc reads them: '#' starts a comment, one option per line.
std::string CheckOptionsFile(const std::string &option, const std::string &name, const std::string &where, int depth)
{
  if (name.empty() || name[0] == '-') return Format("option %s%s: no file name given", option.c_str(), where.c_str());
  if (name[0] == '~' || name.find('$') != std::string::npos) return "";
  auto        endsWith = [](const std::string &s, const char *tail) { return s.size() >= std::strlen(tail) && s.compare(s.size() - std::strlen(tail), std::string::npos, tail) == 0; };
  const bool  tagged   = endsWith(name, ":yaml"); // PETSc's way to name a YAML file of any name
  std::string path     = tagged ? name.substr(0, name.size() - 5) : name;
  // YAML files are only opened here: what they include is left to PETSc
  const bool yaml = tagged || strcasecmp(option.c_str(), "-options_file_yaml") == 0 || endsWith(path, ".yaml") || endsWith(path, ".yml") || endsWith(path, ".json");
  struct stat st;
  if (stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) return Format("option %s%s: '%s' is a directory, not an options file", option.c_str(), where.c_str(), path.c_str());
  FILE *fp = std::fopen(path.c_str(), "r");
  if (!fp) return Format("option %s%s: cannot open '%s' (%s)", option.c_str(), where.c_str(), path.c_str(), std::strerror(errno));
  std::vector<std::string> tokens;
  char                     line[4096];
  while (!yaml && depth < kMaxDepth && std::fgets(line, sizeof line, fp)) {
    if (char *comment = std::strchr(line, '#')) *comment = 0;
    std::istringstream words(line);
    for (std::string w; words >> w;) tokens.push_back(w);
  }
  std::fclose(fp);
  return CheckFiles(tokens, " in '" + path + "'", depth + 1);
}

std::string CheckFiles(const std::vector<std::string> &tokens, const std::string &where, int depth)
{
  for (size_t i = 0; i < tokens.size(); ++i) {
    const char *t = tokens[i].c_str();
    if (strcasecmp(t, "-options_file") && strcasecmp(t, "-options_file_yaml")) continue;
    std::string problem = CheckOptionsFile(t, i + 1 < tokens.size() ? tokens[i + 1] : "", where, depth);
    if (!problem.empty()) return problem;
  }
  return "";
}

} // namespace

int StartMPI(int *argc, char ***argv, const char *program)
{
  // PT-Scotch (the redistribution of adapted meshes, -mesh_partitioner ptscotch) spreads its partitioning
  // over threads by default, and their timing changes the partition, and with it the solver's round-off,
  // from one run to the next. One thread per rank makes a run reproducible and leaves the cores to the
  // ranks; a user's own SCOTCH_PTHREAD_NUMBER is kept.
  setenv("SCOTCH_PTHREAD_NUMBER", "1", 0);
  int provided, rank;
  MPI_Init_thread(argc, argv, PETSC_MPI_THREAD_REQUIRED, &provided); // the level PetscInitialize would ask for
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  char problem[1024] = "";
  if (rank == 0) {
    std::vector<std::string> tokens;
    if (const char *env = std::getenv("PETSC_OPTIONS")) {
      std::istringstream words(env);
      for (std::string w; words >> w;) tokens.push_back(w);
    }
    std::string found = CheckFiles(tokens, " in PETSC_OPTIONS", 0);
    if (found.empty()) found = CheckFiles(std::vector<std::string>(*argv + 1, *argv + *argc), "", 0);
    std::snprintf(problem, sizeof problem, "%s", found.c_str());
  }
  MPI_Bcast(problem, sizeof problem, MPI_CHAR, 0, MPI_COMM_WORLD);
  if (!problem[0]) return 0;
  if (rank == 0) std::fprintf(stderr, "%s: error: %s\n", program, problem);
  MPI_Finalize();
  return 1;
}

} // namespace signorini
