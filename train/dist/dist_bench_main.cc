// lmb_dist_bench: the distributed training benchmark (train/dist/dist_bench.h).
//   mpirun -n R lmb_dist_bench [--rounds N] [--classes C] [--dims-per-round K] [--out report.json]
// Without a launcher it runs on one process.
#include <cstdio>

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "common/file_io.h"
#include "train/dist/dist_bench.h"

int main(int argc, char** argv) {
  CLI::App app{"Distributed JointBoost training benchmark (paper-shape synthetic problem by default)"};
  lmb::BoostBenchOptions options;
  std::string out;
  app.add_option("--rounds", options.rounds, "timed rounds");
  app.add_option("--classes", options.data.num_classes, "landmark classes (paper: 7,500)");
  app.add_option("--dims-per-round", options.boost.dims_per_round, "|F_m| (paper: 500)");
  app.add_option("--out", out, "also write the JSON report here (rank 0)");
  CLI11_PARSE(app, argc, argv);
  try {
    lmb::MpiSession mpi;
    lmb::Communicator comm = lmb::Communicator::world(mpi);
    const std::string report = lmb::run_dist_bench(comm, options);
    if (comm.rank() == 0) {
      std::printf("%s\n", report.c_str());
      if (!out.empty()) lmb::write_file_atomically(out, report + "\n");
    }
  } catch (const lmb::Error& e) {
    std::fprintf(stderr, "lmb_dist_bench: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
