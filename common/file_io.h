// The file I/O core every reader and writer of the project goes through (no MPI, HDF5 or OpenCV:
// infer links it too).
//
// Writing: AtomicFile. A file is written to a temporary beside its final path, ".NAME.tmp-PID"
// (same folder, so the rename cannot cross file systems), then flushed, fsync'ed, closed (each step
// checked: NFS and quotas report errors at close), renamed over the final path, and the folder is
// fsync'ed. The final path holds either its old content or the whole new one: never a 0-byte or a
// partial file. On any failure, or when an AtomicFile is destroyed before commit(), the temporary
// is removed. Errors are lmb::Error "<final path>: <step> failed: <system reason>".
//
// Libraries that write files by name themselves (HDF5) write AtomicFile::temp_path() and leave the
// rest to commit(). Append-only logs (metrics.jsonl) use AppendFile, whose every write is checked.
//
// Reading: read_file() reads a whole regular file with errors naming it (a folder, a device, a
// read error). Text files: common/text_lines.h; binary payloads: common/bounded_reader.h.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace lmb {

class AtomicFile {
 public:
  // Creates the temporary ".NAME.tmp-PID" beside `path` (removing a stale one of this process).
  // Throws lmb::Error naming `path`: its folder is missing or not writable, `path` is a folder.
  explicit AtomicFile(std::filesystem::path path);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  // Without commit(): closes and removes the temporary; the final path is untouched.
  ~AtomicFile();

  const std::filesystem::path& path() const { return path_; }
  const std::filesystem::path& temp_path() const { return temp_; }

  // Appends to the temporary. Throws lmb::Error "<path>: write failed: <reason>" (the temporary is
  // removed, later calls throw too).
  void write(const void* data, size_t size);
  void write(std::string_view text) { write(text.data(), text.size()); }

  // fsync + close of the temporary, rename over path(), fsync of the folder. Throws lmb::Error
  // naming path() and the failed step; the temporary is removed and path() keeps its old content.
  void commit();

 private:
  [[noreturn]] void fail(const char* step, int error);
  void discard();
  std::filesystem::path path_;
  std::filesystem::path temp_;
  int fd_ = -1;
  bool done_ = false;
};

// The whole file in one AtomicFile.
void write_file_atomically(const std::filesystem::path& path, const void* data, size_t size);
void write_file_atomically(const std::filesystem::path& path, std::string_view text);

// Fails early, before a long job, when `path` could not be written later: its folder (created if
// `create_folder`) is missing or not writable, or `path` is a folder. `what` names the option in the
// message ("--out"). Creates and removes a temporary to be sure (root ignores permission bits; a
// read-only mount does not). Throws lmb::Error.
void check_writable_file(const std::filesystem::path& path, const std::string& what, bool create_folder = true);

// The same for a folder a command will write into (created when missing).
void check_writable_folder(const std::filesystem::path& folder, const std::string& what);

// A file or folder a command reads or writes, and the option that names it ("--map"). `folder`: the
// command reads or writes it as a folder (a collection's sparse model, a run folder), not a file.
struct NamedPath {
  std::filesystem::path path;
  std::string what;
  bool folder = false;
};

// Inputs are never outputs: fails, before any work, when one of a command's outputs would replace
// or write into one of its inputs. An output is refused when it is the same file or folder as an
// input (same device and inode when both exist: a hard link, a symbolic link, "./x" for "x"; else
// the same absolute path with symbolic links resolved), when it lies inside an input folder, or
// when it is an output folder that contains an input. (Nothing can be written inside a file, and
// a file output cannot replace a folder: a path given for a file that is a folder is left to the
// reader or writer, which says so.) Entries with an empty path (an option not given) are skipped.
// Throws lmb::Error, one line naming both: "--out m1.h5 is the input --map m1.h5 (an output never
// replaces an input)", "... lies inside the input ...", "... contains the input ...".
void check_outputs_not_inputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs);

// Whether `a` and `b` name the same file or folder, as check_outputs_not_inputs compares them.
bool same_file(const std::filesystem::path& a, const std::filesystem::path& b);

// Removes temporaries ".<anything>.tmp-PID" in `folder` whose writer (PID) no longer runs on this
// machine: left by a process killed while it wrote. Never fails.
void remove_stale_temporaries(const std::filesystem::path& folder);

// An append-only text file (a log): every write is checked and flushed to the kernel; close() or
// the destructor fsyncs. Throws lmb::Error "<path>: write failed: <reason>".
class AppendFile {
 public:
  AppendFile() = default;
  // Opens (creates) `path` for appending. Throws lmb::Error naming it.
  explicit AppendFile(const std::filesystem::path& path);
  AppendFile(AppendFile&& other) noexcept;
  AppendFile& operator=(AppendFile&& other) noexcept;
  ~AppendFile();
  bool is_open() const { return fd_ >= 0; }
  void write(std::string_view text);
  // fsync + close, checked.
  void close();

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

// An exclusive advisory lock (flock(2)) on a lock file, held until the object is destroyed or the
// process ends (also by a crash or kill -9: the kernel releases it). Local file systems, and NFS
// (Linux emulates flock with NFS byte-range locks, so hosts see each other's locks unless the
// mount uses `nolock` or `local_lock`), support it; where the file system has no locks at all
// (Lustre without `-o flock`) try_lock reports kUnsupported.
class FileLock {
 public:
  enum class Status { kLocked, kBusy, kUnsupported };
  FileLock() = default;
  FileLock(FileLock&& other) noexcept;
  FileLock& operator=(FileLock&& other) noexcept;
  ~FileLock();
  // Opens (creates, mode 0666 & ~umask) `path` and tries to lock it without waiting. kBusy: another
  // open file holds it; `holder` (if given) then receives "pid N" when /proc/locks names the
  // holder on this machine, else "". Throws lmb::Error naming the path when it cannot be opened.
  Status try_lock(const std::filesystem::path& path, std::string* holder = nullptr);
  bool locked() const { return fd_ >= 0; }
  void unlock();

 private:
  int fd_ = -1;
};

// Reads a whole regular file (symbolic links followed). Throws lmb::Error "<path>: <reason>":
// missing, a folder or not a regular file, unreadable, read error; also when it exceeds max_bytes.
std::string read_file(const std::filesystem::path& path, uint64_t max_bytes = UINT64_MAX);

namespace detail {
// Test hook: the next AtomicFile step of this kind fails with `error` (an errno value) as if the
// system had reported it. kNone disables. Used by test/common/file_io_test.cc only.
enum class FileFault { kNone, kWrite, kFsync, kClose, kRename, kSyncFolder };
void inject_file_fault(FileFault fault, int error);
}  // namespace detail

}  // namespace lmb
