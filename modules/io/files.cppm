module;
#include <fcntl.h>
#include <stdio.h>  // ::rename
#include <sys/stat.h>
#include <unistd.h>

#include <errno.h>
export module peridot.io:files;
import peridot.std;

// The two ways Peridot writes files, each checking every byte: a whole file replaced
// atomically, and a log that grows by whole records. A full disk, a quota or a vanished
// directory is a std::runtime_error naming the file, never a silently short output.
export namespace peridot {

// Writes the parts, one after another, to `file.tmp` and renames it over `file`, so a
// reader never sees a half-written file. On any failure file.tmp is removed, `file` keeps
// its previous content, and the error names `file` and the reason.
void write_file_atomically(const std::filesystem::path& file, std::initializer_list<std::string_view> parts);

// A file that grows by whole records (CSV rows). A record that cannot be written in full is
// cut off again, so the file holds whole records only, and the error names the file.
class RecordFile {
 public:
  // Truncates (or creates) the file; with `keep`, opens it for appending after its content.
  explicit RecordFile(const std::filesystem::path& file, bool keep = false);
  ~RecordFile();
  RecordFile(const RecordFile&) = delete;
  RecordFile& operator=(const RecordFile&) = delete;
  void append(std::string_view record);
  const std::filesystem::path& path() const { return file_; }

 private:
  std::filesystem::path file_;
  int fd_ = -1;
  off_t size_ = 0;  // bytes of whole records
};

}  // namespace peridot

namespace peridot {

namespace {

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what, int error) {
  throw std::runtime_error(fmt::format("cannot write {}: {}: {}", file.string(), what, std::strerror(error)));
}

// write(2) until every byte is out; false with errno set on failure (ENOSPC, EDQUOT, EIO).
bool write_all(int fd, std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    if (n == 0) {
      errno = EIO;
      return false;
    }
    bytes.remove_prefix(std::size_t(n));
  }
  return true;
}

}  // namespace

void write_file_atomically(const std::filesystem::path& file, std::initializer_list<std::string_view> parts) {
  const std::string tmp = file.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail(file, fmt::format("cannot create {}", tmp), errno);
  const auto abandon = [&](const std::string& what, int error) {
    ::unlink(tmp.c_str());
    fail(file, what, error);
  };
  for (const auto part : parts)
    if (!write_all(fd, part)) {
      const int error = errno;
      ::close(fd);
      abandon(fmt::format("writing {}", tmp), error);
    }
  // close() reports what the file system only noticed at the end (NFS, quotas).
  if (::close(fd) != 0) abandon(fmt::format("closing {}", tmp), errno);
  if (::rename(tmp.c_str(), file.c_str()) != 0) abandon(fmt::format("renaming {} over it", tmp), errno);
}

RecordFile::RecordFile(const std::filesystem::path& file, bool keep) : file_(file) {
  fd_ = ::open(file.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC | (keep ? 0 : O_TRUNC), 0644);
  if (fd_ < 0) fail(file_, "cannot open it", errno);
  size_ = keep ? ::lseek(fd_, 0, SEEK_END) : 0;
  if (size_ < 0) {
    const int error = errno;
    ::close(fd_);
    fail(file_, "cannot seek to its end", error);
  }
}

RecordFile::~RecordFile() {
  if (fd_ >= 0) ::close(fd_);
}

void RecordFile::append(std::string_view record) {
  if (fd_ < 0) throw std::runtime_error(fmt::format("cannot write {}: an earlier write failed", file_.string()));
  if (::lseek(fd_, size_, SEEK_SET) == size_ && write_all(fd_, record)) {
    size_ += off_t(record.size());
    return;
  }
  const int error = errno;
  // Cut the partial record off, so a reader (or a restart) finds whole rows only.
  [[maybe_unused]] const int cut = ::ftruncate(fd_, size_);
  ::close(fd_);
  fd_ = -1;
  fail(file_, "appending a record", error);
}

}  // namespace peridot
