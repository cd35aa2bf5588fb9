#include "common/file_io.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>
#include <utility>
#include <vector>

#include "common/error.h"

namespace lmb {

namespace fs = std::filesystem;

namespace detail {
namespace {
std::atomic<int> g_fault{static_cast<int>(FileFault::kNone)};
std::atomic<int> g_fault_error{0};
}  // namespace

void inject_file_fault(FileFault fault, int error) {
  g_fault_error = error;
  g_fault = static_cast<int>(fault);
}
}  // namespace detail

namespace {

// The injected error of `step` (once), else 0.
int injected(detail::FileFault step) {
  int expected = static_cast<int>(step);
  if (detail::g_fault.load() != expected) return 0;
  if (!detail::g_fault.compare_exchange_strong(expected, static_cast<int>(detail::FileFault::kNone))) return 0;
  return detail::g_fault_error.load();
}

fs::path folder_of(const fs::path& path) { return path.has_parent_path() ? path.parent_path() : fs::path("."); }

int close_retry(int fd) {
  // close() is not retried on EINTR (Linux releases the descriptor anyway); report it as is.
  return ::close(fd);
}

}  // namespace

AtomicFile::AtomicFile(fs::path path) : path_(std::move(path)) {
  LMB_CHECK(!path_.empty() && path_.has_filename(), "'" << path_.string() << "': not a file name");
  std::error_code ec;
  LMB_CHECK(!fs::is_directory(path_, ec), path_.string() << ": is a folder, not a file");
  const fs::path dir = folder_of(path_);
  std::string base = ".";  // built step by step: GCC 12 warns falsely (-Wrestrict) on "." + string
  base += path_.filename().string();
  base += ".tmp-";
  base += std::to_string(::getpid());
  for (int attempt = 0; attempt < 1000 && fd_ < 0; ++attempt) {
    temp_ = dir / (attempt == 0 ? base : base + "-" + std::to_string(attempt));
    fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd_ < 0 && errno != EEXIST) {
      const int err = errno;
      done_ = true;
      if (err == ENOENT)
        LMB_FAIL(path_.string() << ": cannot create the file: folder " << dir.string() << " does not exist");
      LMB_FAIL(path_.string() << ": cannot create the file: " << std::strerror(err));
    }
  }
  if (fd_ < 0) {
    done_ = true;
    LMB_FAIL(path_.string() << ": cannot create a temporary file beside it (1000 exist)");
  }
}

AtomicFile::~AtomicFile() {
  if (!done_) discard();
}

void AtomicFile::discard() {
  if (fd_ >= 0) {
    close_retry(fd_);
    fd_ = -1;
  }
  if (!temp_.empty()) ::unlink(temp_.c_str());
  done_ = true;
}

void AtomicFile::fail(const char* step, int error) {
  discard();
  LMB_FAIL(path_.string() << ": " << step << " failed: " << std::strerror(error));
}

void AtomicFile::write(const void* data, size_t size) {
  LMB_CHECK(!done_ && fd_ >= 0, path_.string() << ": write after the file was closed or failed");
  if (const int err = injected(detail::FileFault::kWrite)) fail("write", err);
  const auto* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd_, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail("write", errno);
    if (n == 0) fail("write", ENOSPC);
    p += n;
    size -= static_cast<size_t>(n);
  }
}

void AtomicFile::commit() {
  LMB_CHECK(!done_ && fd_ >= 0, path_.string() << ": commit after the file was closed or failed");
  if (const int err = injected(detail::FileFault::kFsync)) fail("fsync", err);
  if (::fsync(fd_) != 0) fail("fsync", errno);
  const int fd = fd_;
  fd_ = -1;
  int err = injected(detail::FileFault::kClose);
  if (close_retry(fd) != 0 && err == 0) err = errno;
  if (err != 0) fail("close", err);
  err = injected(detail::FileFault::kRename);
  if (err == 0 && ::rename(temp_.c_str(), path_.c_str()) != 0) err = errno;
  if (err != 0) fail("rename", err);
  done_ = true;
  // The rename is durable once the folder is synced. Some file systems cannot sync a folder
  // (EINVAL); the file itself is complete either way.
  const fs::path dir = folder_of(path_);
  err = injected(detail::FileFault::kSyncFolder);
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    if (err == 0 && ::fsync(dfd) != 0 && errno != EINVAL && errno != ENOTSUP) err = errno;
    close_retry(dfd);
  }
  LMB_CHECK(err == 0, path_.string() << ": written, but syncing its folder failed: " << std::strerror(err));
}

void write_file_atomically(const fs::path& path, const void* data, size_t size) {
  AtomicFile file(path);
  file.write(data, size);
  file.commit();
}

void write_file_atomically(const fs::path& path, std::string_view text) {
  write_file_atomically(path, text.data(), text.size());
}

void check_writable_file(const fs::path& path, const std::string& what, bool create_folder) {
  try {
    LMB_CHECK(!path.empty(), "an empty path");
    const fs::path dir = folder_of(path);
    std::error_code ec;
    if (create_folder && !fs::exists(dir, ec)) {
      fs::create_directories(dir, ec);
      LMB_CHECK(!ec, path.string() << ": cannot create folder " << dir.string() << ": " << ec.message());
    }
    LMB_CHECK(fs::is_directory(dir, ec), path.string() << ": " << dir.string() << " is not a folder");
    AtomicFile probe(path);  // created, then removed by the destructor
  } catch (const Error& e) {
    LMB_FAIL(what << ": " << e.what());
  }
}

void check_writable_folder(const fs::path& folder, const std::string& what) {
  try {
    LMB_CHECK(!folder.empty(), "an empty path");
    std::error_code ec;
    if (fs::exists(folder, ec)) {
      LMB_CHECK(fs::is_directory(folder, ec), folder.string() << ": exists and is not a folder");
    } else {
      fs::create_directories(folder, ec);
      LMB_CHECK(!ec, folder.string() << ": cannot create the folder: " << ec.message());
    }
    AtomicFile probe(folder / ".lboost-write-probe");
  } catch (const Error& e) {
    LMB_FAIL(what << ": " << e.what());
  }
}

namespace {

// A file's identity: its device and inode (stat(2), symbolic links followed), when it exists.
struct FileId {
  bool exists = false;
  dev_t dev = 0;
  ino_t ino = 0;
  bool operator==(const FileId& o) const { return exists && o.exists && dev == o.dev && ino == o.ino; }
};

FileId file_id(const fs::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return FileId{};
  return FileId{true, st.st_dev, st.st_ino};
}

// The absolute path, symbolic links resolved as far as it exists, normalized, without a trailing
// separator.
fs::path resolved_path(const fs::path& path) {
  std::error_code ec;
  fs::path absolute = fs::absolute(path, ec);
  if (ec) absolute = path;
  fs::path r = fs::weakly_canonical(absolute, ec);
  if (ec) r = absolute;
  r = r.lexically_normal();
  if (!r.has_filename() && r.has_relative_path()) r = r.parent_path();
  return r;
}

// A path as check_outputs_not_inputs compares it.
struct ComparedPath {
  explicit ComparedPath(const fs::path& path) : resolved(resolved_path(path)), id(file_id(resolved)) {}
  fs::path resolved;
  FileId id;
};

bool same(const ComparedPath& a, const ComparedPath& b) { return a.id == b.id || a.resolved == b.resolved; }

// Whether `path` lies (strictly) inside `folder`: by name, or an existing folder above `path` is
// `folder` itself (a bind mount, another spelling the names do not show).
bool lies_inside(const ComparedPath& path, const ComparedPath& folder) {
  const fs::path& p = path.resolved;
  const fs::path& f = folder.resolved;
  auto pi = p.begin();
  bool prefix = true;
  for (auto fi = f.begin(); fi != f.end() && prefix; ++fi, ++pi) prefix = pi != p.end() && *pi == *fi;
  if (prefix && pi != p.end()) return true;
  if (!folder.id.exists) return false;
  for (fs::path up = p.parent_path(); up.has_relative_path(); up = up.parent_path()) {
    if (file_id(up) == folder.id) return true;
  }
  return false;
}

}  // namespace

void check_outputs_not_inputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs) {
  std::vector<std::pair<const NamedPath*, ComparedPath>> in;
  for (const NamedPath& i : inputs) {
    if (!i.path.empty()) in.emplace_back(&i, ComparedPath(i.path));
  }
  for (const NamedPath& o : outputs) {
    if (o.path.empty()) continue;
    const ComparedPath out(o.path);
    for (const auto& [input, compared] : in) {
      const char* relation = same(out, compared)                           ? "is"
                             : input->folder && lies_inside(out, compared) ? "lies inside"
                             : o.folder && lies_inside(compared, out)      ? "contains"
                                                                           : nullptr;
      if (relation == nullptr) continue;
      LMB_FAIL(o.what << " " << o.path.string() << " " << relation << " the input " << input->what << " "
                      << input->path.string() << " (an output never replaces an input)");
    }
  }
}

bool same_file(const fs::path& a, const fs::path& b) { return same(ComparedPath(a), ComparedPath(b)); }

void remove_stale_temporaries(const fs::path& folder) {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    const size_t at = name.rfind(".tmp-");
    if (name.empty() || name[0] != '.' || at == std::string::npos || at == 0) continue;
    const char* digits = name.c_str() + at + 5;
    char* end = nullptr;
    const long pid = std::strtol(digits, &end, 10);
    if (end == digits || pid <= 0 || pid == ::getpid()) continue;
    if (*end == '-') {  // ".tmp-PID-N"
      const char* n = end + 1;
      std::strtol(n, &end, 10);
      if (end == n) continue;
    }
    if (*end != '\0') continue;
    if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) {
      std::error_code rm;
      fs::remove(entry.path(), rm);
    }
  }
}

AppendFile::AppendFile(const fs::path& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0666);
  const int err = errno;
  LMB_CHECK(fd_ >= 0, path.string() << ": cannot open for appending: " << std::strerror(err));
}

AppendFile::AppendFile(AppendFile&& other) noexcept : path_(std::move(other.path_)), fd_(other.fd_) { other.fd_ = -1; }

AppendFile& AppendFile::operator=(AppendFile&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) close_retry(fd_);
    path_ = std::move(other.path_);
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

AppendFile::~AppendFile() {
  if (fd_ >= 0) {
    ::fsync(fd_);
    close_retry(fd_);
  }
}

void AppendFile::write(std::string_view text) {
  LMB_CHECK(fd_ >= 0, path_.string() << ": write to a closed file");
  const char* p = text.data();
  size_t left = text.size();
  while (left > 0) {
    const ssize_t n = ::write(fd_, p, left);
    if (n < 0 && errno == EINTR) continue;
    const int err = n < 0 ? errno : ENOSPC;
    LMB_CHECK(n > 0, path_.string() << ": write failed: " << std::strerror(err));
    p += n;
    left -= static_cast<size_t>(n);
  }
}

void AppendFile::close() {
  if (fd_ < 0) return;
  const int fd = fd_;
  fd_ = -1;
  int err = ::fsync(fd) != 0 && errno != EINVAL ? errno : 0;
  if (close_retry(fd) != 0 && err == 0) err = errno;
  LMB_CHECK(err == 0, path_.string() << ": close failed: " << std::strerror(err));
}

FileLock::FileLock(FileLock&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }

FileLock& FileLock::operator=(FileLock&& other) noexcept {
  if (this != &other) {
    unlock();
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

FileLock::~FileLock() { unlock(); }

void FileLock::unlock() {
  if (fd_ >= 0) {
    ::flock(fd_, LOCK_UN);
    close_retry(fd_);
    fd_ = -1;
  }
}

namespace {
// "pid N" of the process holding a lock on the file with this device and inode, from /proc/locks
// (lines "1: FLOCK  ADVISORY  WRITE 1234 08:01:5678 0 EOF"); "" when not found.
std::string lock_holder(dev_t dev, ino_t ino) {
  std::ifstream in("/proc/locks");
  std::string line;
  char want[64];
  std::snprintf(want, sizeof(want), "%02x:%02x:%llu", major(dev), minor(dev), static_cast<unsigned long long>(ino));
  while (std::getline(in, line)) {
    std::istringstream f(line);
    std::string id, kind, mode, access, pid, file;
    if (!(f >> id >> kind)) continue;
    if (kind == "->") continue;  // a waiter
    if (!(f >> mode >> access >> pid >> file)) continue;
    if (kind == "FLOCK" && file == want) return "pid " + pid;
  }
  return "";
}
}  // namespace

FileLock::Status FileLock::try_lock(const fs::path& path, std::string* holder) {
  unlock();
  if (holder) holder->clear();
  // Read-write: NFS implements an exclusive flock as a write lock, which needs a writable file.
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
  const int open_error = errno;
  LMB_CHECK(fd >= 0, path.string() << ": cannot open the lock file: " << std::strerror(open_error));
  if (::flock(fd, LOCK_EX | LOCK_NB) == 0) {
    fd_ = fd;
    return Status::kLocked;
  }
  const int err = errno;
  if (err == EWOULDBLOCK && holder) {
    struct stat st {};
    if (::fstat(fd, &st) == 0) *holder = lock_holder(st.st_dev, st.st_ino);
  }
  close_retry(fd);
  if (err == EWOULDBLOCK) return Status::kBusy;
  if (err == ENOLCK || err == ENOSYS || err == EOPNOTSUPP || err == EINVAL) return Status::kUnsupported;
  LMB_FAIL(path.string() << ": cannot lock: " << std::strerror(err));
}

std::string read_file(const fs::path& path, uint64_t max_bytes) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  const int open_error = errno;
  LMB_CHECK(fd >= 0, path.string() << ": cannot open file: " << std::strerror(open_error));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  LMB_CHECK(::fstat(fd, &st) == 0, path.string() << ": cannot read file");
  LMB_CHECK(!S_ISDIR(st.st_mode), path.string() << ": is a folder, not a file");
  LMB_CHECK(S_ISREG(st.st_mode), path.string() << ": not a regular file");
  LMB_CHECK(static_cast<uint64_t>(st.st_size) <= max_bytes,
            path.string() << ": file of " << st.st_size << " bytes exceeds the limit of " << max_bytes);
  std::string bytes;
  bytes.reserve(static_cast<size_t>(st.st_size));
  char buffer[1 << 16];
  while (true) {
    const ssize_t n = ::read(fd, buffer, sizeof(buffer));
    if (n < 0 && errno == EINTR) continue;
    const int err = errno;
    LMB_CHECK(n >= 0, path.string() << ": read error: " << std::strerror(err));
    if (n == 0) break;
    LMB_CHECK(bytes.size() + static_cast<size_t>(n) <= max_bytes,
              path.string() << ": file exceeds the limit of " << max_bytes << " bytes");
    bytes.append(buffer, static_cast<size_t>(n));
  }
  return bytes;
}

}  // namespace lmb
