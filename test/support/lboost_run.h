// The CLI tests' one runner: runs the build's lboost (LMB_LBOOST, a compile definition of each CLI
// test target) or lboost-bench (LMB_LBOOST_BENCH) in a folder and captures its exit code and both
// streams.
#pragma once

#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace lmb::test {

struct RunResult {
  int exit_code = 0;  // -1 when lboost did not exit normally (a signal)
  std::string out;
  std::string err;
};

// The whole file, bytes as they are ("" when it cannot be read).
inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Runs `prefix program args` (prefix: e.g. "mpiexec -n 2 ") with `dir` holding the captured
// streams, which are removed afterwards.
inline RunResult run_program(const std::string& program, const std::string& args, const std::filesystem::path& dir,
                             const std::string& prefix = "") {
  static int counter = 0;
  const std::string tag = std::to_string(++counter);
  const std::filesystem::path out = dir / ("stdout_" + tag + ".txt"), err = dir / ("stderr_" + tag + ".txt");
  const std::string command = prefix + program + " " + args + " > " + out.string() + " 2> " + err.string();
  const int status = std::system(command.c_str());
  RunResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  std::filesystem::remove(out);
  std::filesystem::remove(err);
  return r;
}

#ifdef LMB_LBOOST
inline RunResult run_lboost(const std::string& args, const std::filesystem::path& dir, const std::string& prefix = "") {
  return run_program(LMB_LBOOST, args, dir, prefix);
}
#endif

#ifdef LMB_LBOOST_BENCH
inline RunResult run_lboost_bench(const std::string& args, const std::filesystem::path& dir,
                                  const std::string& prefix = "") {
  return run_program(LMB_LBOOST_BENCH, args, dir, prefix);
}
#endif

// The run failed with exit code 1 and one line on stderr, "PROGRAM COMMAND: error: ...", holding
// `needle` (the project's rule for every error: docs/input_validation.md).
inline void expect_one_error(const RunResult& r, const std::string& command, const std::string& needle,
                             const std::string& program = "lboost") {
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(r.err.rfind(program + " " + command + ": error: ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << "expected '" << needle << "' in: " << r.err;
}

}  // namespace lmb::test
