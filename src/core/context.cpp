#include "flexopt/core/context.hpp"

#include "flexopt/core/error.hpp"

#include <cstdarg>
#include <cstdio>
#include <slepcsys.h>
#include <sstream>

namespace flexopt {

Context::Context(int *argc, char ***argv, const char *help) {
  PetscErrorCode ierr = SlepcInitialize(argc, argv, nullptr, help);
  if (ierr) throw Error("could not initialise PETSc/SLEPc");
  comm_ = PETSC_COMM_WORLD;
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
}

Context::~Context() {
  SlepcFinalize();
}

int comm_rank(MPI_Comm comm) {
  int r = 0;
  MPI_Comm_rank(comm, &r);
  return r;
}

int comm_size(MPI_Comm comm) {
  int s = 1;
  MPI_Comm_size(comm, &s);
  return s;
}

void run_on_root(MPI_Comm comm, int root, const std::function<void()> &fn) {
  std::string message;
  int failed = 0;
  if (comm_rank(comm) == root) {
    try {
      fn();
    } catch (const std::exception &e) {
      failed = 1;
      message = e.what();
    }
  }
  MPI_Bcast(&failed, 1, MPI_INT, root, comm);
  if (!failed) return;
  broadcast_text(comm, message, root);
  throw Error(message, /*collective=*/true);
}

void broadcast_text(MPI_Comm comm, std::string &s, int root) {
  long long n = static_cast<long long>(s.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, root, comm);
  s.resize(static_cast<std::size_t>(n));
  MPI_Bcast(s.data(), static_cast<int>(n), MPI_CHAR, root, comm);
}

namespace {
std::string g_prefix;        ///< PrintPrefix's
bool g_at_line_start = true; ///< the last character print0 wrote ended a line
} // namespace

PrintPrefix::PrintPrefix(const std::string &prefix) {
  g_prefix = prefix;
}
PrintPrefix::~PrintPrefix() {
  g_prefix.clear();
}

void print0(MPI_Comm comm, const char *format, ...) {
  if (comm_rank(comm) != 0) return;
  va_list args;
  va_start(args, format);
  if (g_prefix.empty()) {
    std::vprintf(format, args);
  } else {
    va_list copy;
    va_copy(copy, args);
    const int n = std::vsnprintf(nullptr, 0, format, copy);
    va_end(copy);
    std::string text(static_cast<std::size_t>(std::max(n, 0)) + 1, '\0');
    std::vsnprintf(text.data(), text.size(), format, args);
    text.resize(static_cast<std::size_t>(std::max(n, 0)));
    std::string out;
    for (char c : text) {
      if (g_at_line_start && c != '\n') out += g_prefix;
      out += c;
      g_at_line_start = c == '\n' || c == '\r';
    }
    std::fputs(out.c_str(), stdout);
  }
  va_end(args);
  std::fflush(stdout);
}

double wall_time() {
  return MPI_Wtime();
}

std::vector<PetscOption> parse_petsc_options(const std::string &options,
                                             const std::string &origin) {
  std::istringstream in(options);
  std::vector<std::string> tokens;
  for (std::string t; in >> t;) tokens.push_back(t);
  std::vector<PetscOption> out;
  for (std::size_t i = 0; i < tokens.size();) {
    const std::string &name = tokens[i];
    if (name.size() < 2 || name[0] != '-' || (name[1] >= '0' && name[1] <= '9'))
      throw Error(origin +
                      ": PETSc option string: expected an option name starting with '-', got '" +
                      name + "'",
                  true);
    // A value follows unless the next token is an option name (a negative number is a value).
    const bool has_value =
        i + 1 < tokens.size() &&
        !(tokens[i + 1][0] == '-' && tokens[i + 1].size() > 1 &&
          !(tokens[i + 1][1] >= '0' && tokens[i + 1][1] <= '9') && tokens[i + 1][1] != '.');
    out.push_back({name, has_value ? tokens[i + 1] : std::string()});
    i += has_value ? 2 : 1;
  }
  return out;
}

void insert_default_petsc_options(const std::string &options, const std::string &origin) {
  for (const PetscOption &o : parse_petsc_options(options, origin)) {
    PetscBool set = PETSC_FALSE;
    FX_PETSC(PetscOptionsHasName(nullptr, nullptr, o.name.c_str(), &set));
    if (!set)
      FX_PETSC(PetscOptionsSetValue(nullptr, o.name.c_str(),
                                    o.value.empty() ? nullptr : o.value.c_str()));
  }
}

} // namespace flexopt
