// The I/O core (common/file_io.h, common/text_lines.h): atomic writes leave the old file or the
// whole new one and no temporary, whatever step fails (real failures through RLIMIT_FSIZE, every
// other step through the fault hook); errors name the file and the system's reason.
#include "common/file_io.h"

#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/text_lines.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

class FileIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_file_io_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    detail::inject_file_fault(detail::FileFault::kNone, 0);
    fs::remove_all(dir_);
  }
  // Every entry of the folder but the given file names: temporaries left behind.
  std::vector<std::string> others(const std::vector<std::string>& expected) const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      if (std::find(expected.begin(), expected.end(), name) == expected.end()) out.push_back(name);
    }
    return out;
  }
  fs::path dir_;
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST_F(FileIoTest, WritesAndReplacesWithoutLeavingTemporaries) {
  const fs::path path = dir_ / "a.txt";
  write_file_atomically(path, "first");
  EXPECT_EQ(read_file(path), "first");
  write_file_atomically(path, std::string(100000, 'x'));
  EXPECT_EQ(read_file(path), std::string(100000, 'x'));
  write_file_atomically(path, "");
  EXPECT_EQ(read_file(path), "");
  EXPECT_TRUE(others({"a.txt"}).empty());
}

TEST_F(FileIoTest, EveryFailedStepKeepsTheOldFileAndRemovesTheTemporary) {
  const fs::path path = dir_ / "model.lbm";
  const struct {
    detail::FileFault fault;
    int error;
    const char* message;
  } cases[] = {
      {detail::FileFault::kWrite, ENOSPC, ": write failed: No space left on device"},
      {detail::FileFault::kFsync, EIO, ": fsync failed: Input/output error"},
      {detail::FileFault::kClose, EDQUOT, ": close failed: Disk quota exceeded"},
      {detail::FileFault::kRename, EXDEV, ": rename failed: Invalid cross-device link"},
  };
  for (bool existed : {false, true}) {
    for (const auto& c : cases) {
      fs::remove(path);
      if (existed) write_file_atomically(path, "old");
      detail::inject_file_fault(c.fault, c.error);
      EXPECT_EQ(error_of([&] { write_file_atomically(path, std::string(5000, 'n')); }), path.string() + c.message);
      if (existed) {
        EXPECT_EQ(read_file(path), "old");
      } else {
        EXPECT_FALSE(fs::exists(path)) << c.message;
      }
      EXPECT_TRUE(others({"model.lbm"}).empty()) << c.message;
    }
  }
  // The folder sync fails after the rename: the new file is complete, the error says so.
  detail::inject_file_fault(detail::FileFault::kSyncFolder, EIO);
  EXPECT_EQ(error_of([&] { write_file_atomically(path, "new"); }),
            path.string() + ": written, but syncing its folder failed: Input/output error");
  EXPECT_EQ(read_file(path), "new");
  EXPECT_TRUE(others({"model.lbm"}).empty());
}

// The real thing: a file-size limit (RLIMIT_FSIZE) makes write(2) fail with EFBIG as a full disk
// makes it fail with ENOSPC, at any byte.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &saved_);
    old_handler_ = ::signal(SIGXFSZ, SIG_IGN);  // else the kernel kills the process
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    ::setrlimit(RLIMIT_FSIZE, &limit);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &saved_);
    ::signal(SIGXFSZ, old_handler_);
  }

 private:
  rlimit saved_{};
  sighandler_t old_handler_ = SIG_DFL;
};

TEST_F(FileIoTest, RealWriteFailureAtAnySizeLeavesNoPartialFile) {
  const fs::path path = dir_ / "map.h5";
  write_file_atomically(path, "old content");
  for (rlim_t limit : {rlim_t{0}, rlim_t{1}, rlim_t{4095}, rlim_t{4096}, rlim_t{65537}}) {
    std::string message;
    {
      FileSizeLimit l(limit);
      message = error_of([&] { write_file_atomically(path, std::string(200000, 'z')); });
    }
    EXPECT_EQ(message, path.string() + ": write failed: File too large") << "limit " << limit;
    EXPECT_EQ(read_file(path), "old content");
    EXPECT_TRUE(others({"map.h5"}).empty());
  }
  // Appends (logs) are checked too.
  AppendFile log(dir_ / "metrics.jsonl");
  log.write("line 1\n");
  {
    FileSizeLimit l(10);
    EXPECT_EQ(error_of([&] { log.write("line 2 is longer\n"); }),
              (dir_ / "metrics.jsonl").string() + ": write failed: File too large");
  }
  log.close();
}

TEST_F(FileIoTest, DestroyedWithoutCommitLeavesNothing) {
  {
    AtomicFile f(dir_ / "x.bin");
    f.write("abc");
    EXPECT_TRUE(fs::exists(f.temp_path()));
    EXPECT_EQ(f.temp_path().parent_path(), dir_);
  }
  EXPECT_TRUE(others({}).empty());
  // Two writers of one path in one process do not share a temporary.
  AtomicFile a(dir_ / "y.bin"), b(dir_ / "y.bin");
  EXPECT_NE(a.temp_path(), b.temp_path());
  a.write("a");
  b.write("b");
  a.commit();
  b.commit();
  EXPECT_EQ(read_file(dir_ / "y.bin"), "b");
  EXPECT_TRUE(others({"y.bin"}).empty());
}

TEST_F(FileIoTest, BadPathsFailWithOneClearLine) {
  fs::create_directories(dir_ / "folder");
  EXPECT_EQ(error_of([&] { write_file_atomically(dir_ / "folder", "x"); }),
            (dir_ / "folder").string() + ": is a folder, not a file");
  EXPECT_EQ(error_of([&] { write_file_atomically(dir_ / "missing" / "a.json", "x"); }),
            (dir_ / "missing" / "a.json").string() + ": cannot create the file: folder " + (dir_ / "missing").string() +
                " does not exist");
  EXPECT_EQ(error_of([&] { read_file(dir_ / "folder"); }), (dir_ / "folder").string() + ": is a folder, not a file");
  EXPECT_EQ(error_of([&] { read_file(dir_ / "nope"); }),
            (dir_ / "nope").string() + ": cannot open file: No such file or directory");
  EXPECT_EQ(error_of([&] { read_file("/dev/null"); }), "/dev/null: not a regular file");
  write_file_atomically(dir_ / "big", std::string(100, 'b'));
  EXPECT_EQ(error_of([&] { read_file(dir_ / "big", 99); }),
            (dir_ / "big").string() + ": file of 100 bytes exceeds the limit of 99");
  // check_writable_* fail before a long job and name the option; they leave nothing behind.
  EXPECT_EQ(error_of([&] { check_writable_file(dir_ / "folder", "--out"); }),
            "--out: " + (dir_ / "folder").string() + ": is a folder, not a file");
  EXPECT_EQ(error_of([&] { check_writable_folder(dir_ / "big", "--out"); }),
            "--out: " + (dir_ / "big").string() + ": exists and is not a folder");
  EXPECT_NO_THROW(check_writable_file(dir_ / "new" / "map.h5", "--out"));
  EXPECT_TRUE(fs::is_directory(dir_ / "new"));
  EXPECT_TRUE(fs::is_empty(dir_ / "new"));
  EXPECT_NO_THROW(check_writable_folder(dir_ / "run", "--out"));
  EXPECT_TRUE(fs::is_empty(dir_ / "run"));
}

TEST_F(FileIoTest, StaleTemporariesOfDeadWritersAreRemoved) {
  // A pid no process can have: the kernel's pid_max (pids are below it). (Not a forked child that
  // exited: fork hangs under some qemu-user builds, and the cross test runs this under qemu.)
  long pid_max = 0;
  std::ifstream("/proc/sys/kernel/pid_max") >> pid_max;
  ASSERT_GT(pid_max, 1) << "cannot read /proc/sys/kernel/pid_max";
  ASSERT_EQ(::kill(static_cast<pid_t>(pid_max), 0), -1);
  ASSERT_EQ(errno, ESRCH);
  const std::string dead = std::to_string(pid_max), alive = std::to_string(::getpid());
  const std::vector<std::string> names = {".ckpt-0000010.h5.tmp-" + dead,
                                          ".ckpt-0000010.h5.tmp-" + dead + "-2",
                                          ".ckpt-0000020.h5.tmp-" + alive,
                                          ".map.h5.tmp-1",  // pid 1 runs
                                          "ckpt-0000030.h5",
                                          ".notes.tmp-x" + dead};
  for (const std::string& name : names) {
    write_file_atomically(dir_ / name, "t");
  }
  remove_stale_temporaries(dir_);
  auto left = others({});
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{".ckpt-0000020.h5.tmp-" + alive, ".map.h5.tmp-1", ".notes.tmp-x" + dead,
                                            "ckpt-0000030.h5"}));
}

TEST_F(FileIoTest, TextLineReaderNumbersDataLines) {
  write_file_atomically(dir_ / "a.txt",
                        "# comment\n\n  \t\nfirst line\r\n  # indented comment\nsecond\tfield  x\nlast");
  TextLineReader r(dir_ / "a.txt");
  ASSERT_TRUE(r.next());
  EXPECT_EQ(r.line(), "first line");
  EXPECT_EQ(r.number(), 4);
  EXPECT_EQ(r.where(), (dir_ / "a.txt").string() + " line 4");
  ASSERT_TRUE(r.next());
  EXPECT_EQ(r.number(), 6);
  EXPECT_EQ(r.tokens(), (std::vector<std::string>{"second", "field", "x"}));
  ASSERT_TRUE(r.next());
  EXPECT_EQ(r.line(), "last");
  EXPECT_EQ(r.number(), 7);
  EXPECT_FALSE(r.next());
  EXPECT_FALSE(r.next());

  // A NUL byte (it would cut every later message short) is an error naming file and line.
  write_file_atomically(dir_ / "b.txt", std::string("1 a\n2 b\n3 im\0age.png\n", 20));
  EXPECT_EQ(error_of([&] { TextLineReader x(dir_ / "b.txt"); }),
            (dir_ / "b.txt").string() + " line 3: contains a NUL byte (not a text file?)");
  EXPECT_EQ(error_of([&] { TextLineReader x(dir_); }), dir_.string() + ": is a folder, not a file");
}

TEST_F(FileIoTest, TextLineReaderSkipsALeadingByteOrderMark) {
  // A comment behind the mark stays a comment; a data line behind it has no stray bytes.
  write_file_atomically(dir_ / "bom.txt", "\xEF\xBB\xBF# comment\r\n1 a\r\n");
  TextLineReader r(dir_ / "bom.txt");
  ASSERT_TRUE(r.next());
  EXPECT_EQ(r.number(), 2);
  EXPECT_EQ(r.tokens(), (std::vector<std::string>{"1", "a"}));
  EXPECT_FALSE(r.next());
  write_file_atomically(dir_ / "bom2.txt",
                        "\xEF\xBB\xBF"
                        "1 a\n2 \xEF\xBB\xBF\n");
  TextLineReader r2(dir_ / "bom2.txt");
  ASSERT_TRUE(r2.next());
  EXPECT_EQ(r2.line(), "1 a");
  EXPECT_EQ(r2.number(), 1);
  ASSERT_TRUE(r2.next());
  EXPECT_EQ(r2.line(), "2 \xEF\xBB\xBF");  // only the first bytes of the file are a mark
  EXPECT_EQ(escape_control_bytes(std::string("a\0b\nc\td\x01", 8)), "a\\0b\\nc\\td\\x01");
}

// Inputs are never outputs: every spelling of an input, a path inside an input folder and a folder
// holding an input are refused with one line naming both options; other paths pass.
TEST_F(FileIoTest, OutputsThatAreInputsAreRefused) {
  const fs::path map = dir_ / "m1.h5", sparse = dir_ / "C" / "sparse";
  write_file_atomically(map, "map");
  fs::create_directories(sparse);
  write_file_atomically(sparse / "images.txt", "images");
  const std::vector<NamedPath> inputs = {{map, "--map"}, {sparse, "--collection", true}, {"", "--vocab"}};
  // `out` as an output file, or as an output folder.
  const auto refusal = [&](const fs::path& out, bool folder = false) {
    return error_of([&] { check_outputs_not_inputs({{out, "--out", folder}}, inputs); });
  };
  const std::string suffix = " (an output never replaces an input)";
  // The same file: the same name, another spelling, a relative one, a hard link, a symbolic link.
  EXPECT_EQ(refusal(map), "--out " + map.string() + " is the input --map " + map.string() + suffix);
  EXPECT_EQ(refusal(dir_ / "." / "C" / ".." / "m1.h5"),
            "--out " + (dir_ / "." / "C" / ".." / "m1.h5").string() + " is the input --map " + map.string() + suffix);
  const fs::path relative = fs::relative(map, fs::current_path());
  ASSERT_TRUE(relative.is_relative());
  EXPECT_EQ(refusal(relative), "--out " + relative.string() + " is the input --map " + map.string() + suffix);
  fs::create_hard_link(map, dir_ / "hard.h5");
  EXPECT_EQ(refusal(dir_ / "hard.h5"),
            "--out " + (dir_ / "hard.h5").string() + " is the input --map " + map.string() + suffix);
  fs::create_symlink(map, dir_ / "soft.h5");
  EXPECT_EQ(refusal(dir_ / "soft.h5"),
            "--out " + (dir_ / "soft.h5").string() + " is the input --map " + map.string() + suffix);
  // Inside an input folder, existing or not, also through a symbolic link to the folder.
  EXPECT_EQ(refusal(sparse / "images.txt"), "--out " + (sparse / "images.txt").string() +
                                                " lies inside the input --collection " + sparse.string() + suffix);
  EXPECT_EQ(refusal(sparse / "new" / "x.txt"), "--out " + (sparse / "new" / "x.txt").string() +
                                                   " lies inside the input --collection " + sparse.string() + suffix);
  fs::create_directory_symlink(sparse, dir_ / "alias");
  EXPECT_EQ(refusal(dir_ / "alias" / "cameras.txt"), "--out " + (dir_ / "alias" / "cameras.txt").string() +
                                                         " lies inside the input --collection " + sparse.string() +
                                                         suffix);
  EXPECT_EQ(refusal(dir_ / "alias"),
            "--out " + (dir_ / "alias").string() + " is the input --collection " + sparse.string() + suffix);
  // An output folder that contains an input (with a trailing separator too), existing or not.
  EXPECT_EQ(refusal(dir_, true), "--out " + dir_.string() + " contains the input --map " + map.string() + suffix);
  EXPECT_EQ(refusal(dir_ / "C" / "", true),
            "--out " + (dir_ / "C" / "").string() + " contains the input --collection " + sparse.string() + suffix);
  const fs::path run = dir_ / "run", config = run / "new.toml";
  EXPECT_EQ(error_of([&] {
              check_outputs_not_inputs({{run, "--out", true}}, {{config, "--config"}});
            }),
            "--out " + run.string() + " contains the input --config " + config.string() + suffix);
  // A path given for a file that is a folder: nothing can be written inside a file, and a file cannot
  // replace a folder (the reader or writer says it is a folder).
  EXPECT_EQ(refusal(dir_), "");
  EXPECT_NO_THROW(check_outputs_not_inputs({{sparse / "poses.json", "--out"}}, {{sparse, "--model"}}));
  // Unrelated paths pass: a sibling, a name that merely starts like an input folder, a new file.
  EXPECT_EQ(refusal(dir_ / "poses.json"), "");
  EXPECT_EQ(refusal(dir_ / "C" / "sparse2" / "x.txt"), "");
  EXPECT_EQ(refusal(dir_ / "C" / "map.h5"), "");
  EXPECT_EQ(refusal(dir_ / "new" / "run"), "");
  EXPECT_NO_THROW(check_outputs_not_inputs({{"", "--json"}, {dir_ / "m2.h5", "--out"}}, inputs));
  EXPECT_NO_THROW(check_outputs_not_inputs({{map, "--out"}}, {}));
  // Neither exists yet: the same path is still the same file.
  EXPECT_EQ(error_of([&] {
              check_outputs_not_inputs({{dir_ / "a.json", "--report"}}, {{dir_ / "a.json", "--map"}});
            }),
            "--report " + (dir_ / "a.json").string() + " is the input --map " + (dir_ / "a.json").string() + suffix);
  // The first output that is an input is named.
  EXPECT_EQ(error_of([&] {
              check_outputs_not_inputs({{dir_ / "ok.json", "--report"}, {map, "--keypoint-ranks"}}, inputs);
            }),
            "--keypoint-ranks " + map.string() + " is the input --map " + map.string() + suffix);
  EXPECT_TRUE(same_file(map, dir_ / "hard.h5"));
  EXPECT_TRUE(same_file(dir_ / "alias", sparse));
  EXPECT_FALSE(same_file(map, sparse));
  EXPECT_EQ(read_file(map), "map");
}

}  // namespace
}  // namespace lmb
