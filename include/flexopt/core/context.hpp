#pragma once
/// \file Process-wide set-up: MPI, PETSc and SLEPc initialisation, and collective helpers.
#include <functional>
#include <mpi.h>
#include <string>
#include <vector>

namespace flexopt {

/// RAII owner of MPI/PETSc/SLEPc. Construct once in main with the PETSc part of the command
/// line; destruction finalises SLEPc and PETSc (and MPI).
class Context {
public:
  Context(int *argc, char ***argv, const char *help);
  ~Context();
  Context(const Context &) = delete;
  Context &operator=(const Context &) = delete;

  MPI_Comm comm() const { return comm_; }
  int rank() const { return rank_; }
  int size() const { return size_; }

private:
  MPI_Comm comm_;
  int rank_ = 0;
  int size_ = 1;
};

/// `s` as `root` holds it, on every rank of `comm`. Collective.
void broadcast_text(MPI_Comm comm, std::string &s, int root = 0);

/// Runs `fn` on `root` only and makes any exception it throws collective: every rank of `comm`
/// then throws a flexopt::Error with the same message. Collective.
void run_on_root(MPI_Comm comm, int root, const std::function<void()> &fn);

/// Rank index and size of a communicator.
int comm_rank(MPI_Comm comm);
int comm_size(MPI_Comm comm);

/// Prints on rank 0 only (printf-style), flushing stdout.
void print0(MPI_Comm comm, const char *format, ...) __attribute__((format(printf, 2, 3)));

/// While it lives, every line print0 writes on this process starts with `prefix` (a scenario's
/// "[fast] " while its group builds and runs it: groups print side by side). Not nested.
class PrintPrefix {
public:
  explicit PrintPrefix(const std::string &prefix);
  ~PrintPrefix();
  PrintPrefix(const PrintPrefix &) = delete;
  PrintPrefix &operator=(const PrintPrefix &) = delete;
};

/// Wall-clock seconds since an arbitrary origin (MPI_Wtime).
double wall_time();

/// Inserts PETSc options from a string (the case's `solver:` entry) without overriding any
/// option already given on the command line. Throws flexopt::Error naming `origin` if the
/// string is malformed.
void insert_default_petsc_options(const std::string &options, const std::string &origin);

/// One option of a PETSc option string: its name ("-ksp_rtol") and value ("" for a flag).
struct PetscOption {
  std::string name, value;
};
/// The options of a PETSc option string in order. Throws flexopt::Error naming `origin` if the
/// string is malformed (a token where an option name belongs that does not start with '-').
std::vector<PetscOption> parse_petsc_options(const std::string &options, const std::string &origin);

} // namespace flexopt
