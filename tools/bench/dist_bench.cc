// `lboost-bench dist`: the distributed training benchmark (train/dist/dist_bench.h), the
// feature-parallel learner on a synthetic problem of the paper's shape by default:
//   mpirun -n R lboost-bench dist [--rounds N] [--classes C] [--dims-per-round K] [--json report.json]
// (the shape options of `lboost-bench boost` too)
// Without a launcher it runs on one process. Rank 0 prints the JSON report (and writes --json).
#include <cstdio>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "common/file_io.h"
#include "tools/bench/bench_commands.h"
#include "train/dist/communicator.h"
#include "train/dist/dist_bench.h"

namespace lmb::bench {

namespace {

struct DistBenchArgs {
  BoostBenchOptions options;
  std::string json;
};

void run_dist_bench_command(const DistBenchArgs& a) {
  MpiSession mpi;
  Communicator comm = Communicator::world(mpi);
  const std::string report = run_dist_bench(comm, a.options);
  if (comm.rank() == 0) {
    std::printf("%s\n", report.c_str());
    if (!a.json.empty()) write_file_atomically(a.json, report + "\n");
  }
}

}  // namespace

void add_dist_bench(CLI::App& app) {
  auto args = std::make_shared<DistBenchArgs>();
  BoostBenchOptions& o = args->options;
  auto* cmd = app.add_subcommand(
      "dist", "Distributed training on MPI ranks (run under mpirun), synthetic data of the paper's shape");
  add_learner_shape_options(cmd, &o);
  cmd->add_option("--json", args->json, "Also write the JSON report here (rank 0)");
  cmd->callback([args] { run_dist_bench_command(*args); });
}

}  // namespace lmb::bench
