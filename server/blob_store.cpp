// The durable embedded store, blob half (server/store.h): content-addressed
// blob files.
//
// Blobs: <root>/<2 hex>/<64 hex>, written as <root>/tmp/<random>.part, fsynced,
// renamed into place and the shard directory fsynced (the classic
// write-temp/fsync/rename/fsync-dir sequence; see "Files are hard", Dan Luu,
// and the ext4/XFS rename notes in Pillai et al., OSDI 2014). A crash leaves
// either no blob or a whole one, plus possibly a stray .part file that
// removeTemporaries deletes.
#include "server/store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openssl/evp.h>
#include <openssl/rand.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>

#include "api/content_id.h"

namespace server {

namespace fs = std::filesystem;
using core::Error;
using core::ErrorCode;
using core::makeError;

// ---------------------------------------------------------------------------
// Hashing

namespace {

constexpr std::size_t kHashHexLength = 64;
constexpr std::size_t kIoChunk = 1 << 16;

std::string toHex(const unsigned char* bytes, std::size_t n) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out(2 * n, '0');
  for (std::size_t i = 0; i < n; ++i) {
    out[2 * i] = kDigits[bytes[i] >> 4];
    out[2 * i + 1] = kDigits[bytes[i] & 0xf];
  }
  return out;
}

// Incremental sha256 over OpenSSL EVP; one per hashing call.
class Sha256 {
 public:
  Sha256() : ctx_(EVP_MD_CTX_new()) {
    const int ok = ctx_ && EVP_DigestInit_ex(ctx_, EVP_sha256(), nullptr) == 1;
    assert(ok && "EVP sha256 init failed");
    (void)ok;
  }
  ~Sha256() { EVP_MD_CTX_free(ctx_); }
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void update(const void* data, std::size_t n) { EVP_DigestUpdate(ctx_, data, n); }
  std::string hex() {
    std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
    unsigned int n = 0;
    EVP_DigestFinal_ex(ctx_, digest.data(), &n);
    return toHex(digest.data(), n);
  }

 private:
  EVP_MD_CTX* ctx_;
};

bool isHashHex(const std::string& hash) {
  if (hash.size() != kHashHexLength) return false;
  for (char c : hash) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  }
  return true;
}

Error ioError(const std::string& what, const fs::path& path, int err) {
  return makeError(ErrorCode::kIo, what + " " + path.string() + ": " + std::strerror(err));
}

// An owned POSIX file descriptor.
class Fd {
 public:
  explicit Fd(int fd = -1) : fd_(fd) {}
  ~Fd() { reset(); }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  bool valid() const { return fd_ >= 0; }
  void reset() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  // close() reporting its error (NFS and friends report write errors here).
  int close() {
    const int rc = ::close(fd_);
    fd_ = -1;
    return rc == 0 ? 0 : errno;
  }

 private:
  int fd_;
};

int openRetrying(const fs::path& path, int flags, mode_t mode = 0) {
  int fd;
  do {
    fd = ::open(path.c_str(), flags | O_CLOEXEC, mode);
  } while (fd < 0 && errno == EINTR);
  return fd;
}

core::Status writeAll(int fd, const std::uint8_t* data, std::size_t n, const fs::path& path) {
  while (n > 0) {
    const ssize_t w = ::write(fd, data, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return ioError("cannot write", path, errno);
    }
    data += w;
    n -= static_cast<std::size_t>(w);
  }
  return core::Ok{};
}

core::Status fsyncPath(const fs::path& path, bool directory) {
  Fd fd(openRetrying(path, directory ? (O_RDONLY | O_DIRECTORY) : O_RDONLY));
  if (!fd.valid()) return ioError("cannot open for fsync", path, errno);
  if (::fsync(fd.get()) != 0) return ioError("cannot fsync", path, errno);
  return core::Ok{};
}

// Creates `dir` (one level) when missing and fsyncs its parent so the entry is
// durable before anything is renamed into it.
core::Status ensureDurableDir(const fs::path& dir) {
  if (::mkdir(dir.c_str(), 0700) == 0) return fsyncPath(dir.has_parent_path() ? dir.parent_path() : ".", true);
  if (errno == EEXIST) return core::Ok{};
  return ioError("cannot create directory", dir, errno);
}

core::Status ensureDurableDirs(const fs::path& dir) {
  std::error_code ec;
  if (fs::is_directory(dir, ec)) return core::Ok{};
  if (dir.has_parent_path() && dir.parent_path() != dir) {
    if (auto st = ensureDurableDirs(dir.parent_path()); !st) return st;
  }
  return ensureDurableDir(dir);
}

std::string randomHex(std::size_t bytes) {
  if (auto hex = secureRandomHex(bytes)) return *hex;
  // Fall back to time and pid: uniqueness, not secrecy, is what matters for temporary names.
  std::vector<unsigned char> buf(bytes);
  const auto t = std::chrono::steady_clock::now().time_since_epoch().count();
  const auto seed = static_cast<unsigned long long>(t) ^ (static_cast<unsigned long long>(::getpid()) << 32);
  for (std::size_t i = 0; i < bytes; ++i) buf[i] = static_cast<unsigned char>(seed >> (8 * (i % 8)));
  return toHex(buf.data(), buf.size());
}

core::Result<std::vector<std::uint8_t>> readWholeFile(const fs::path& path) {
  Fd fd(openRetrying(path, O_RDONLY));
  if (!fd.valid()) return ioError("cannot open", path, errno);
  struct stat st{};
  if (::fstat(fd.get(), &st) != 0) return ioError("cannot stat", path, errno);
  std::vector<std::uint8_t> bytes;
  bytes.reserve(static_cast<std::size_t>(st.st_size));
  std::vector<std::uint8_t> buf(kIoChunk);
  for (;;) {
    const ssize_t r = ::read(fd.get(), buf.data(), buf.size());
    if (r < 0) {
      if (errno == EINTR) continue;
      return ioError("cannot read", path, errno);
    }
    if (r == 0) break;
    bytes.insert(bytes.end(), buf.data(), buf.data() + r);
  }
  return bytes;
}

}  // namespace

core::Result<std::string> sha256HexOfFile(const fs::path& file) {
  Fd fd(openRetrying(file, O_RDONLY));
  if (!fd.valid()) return ioError("cannot open", file, errno);
  Sha256 sha;
  std::vector<std::uint8_t> buf(kIoChunk);
  for (;;) {
    const ssize_t r = ::read(fd.get(), buf.data(), buf.size());
    if (r < 0) {
      if (errno == EINTR) continue;
      return ioError("cannot read", file, errno);
    }
    if (r == 0) break;
    sha.update(buf.data(), static_cast<std::size_t>(r));
  }
  return sha.hex();
}

// ---------------------------------------------------------------------------
// BlobStore

BlobStore::BlobStore(fs::path root) : root_(std::move(root)) {}

fs::path BlobStore::pathOf(const std::string& hash) const {
  assert(hash.size() >= 2);
  return root_ / hash.substr(0, 2) / hash;
}

bool BlobStore::contains(const std::string& hash) const {
  if (!isHashHex(hash)) return false;
  struct stat st{};
  return ::stat(pathOf(hash).c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

namespace {

// Renames `from` to the blob path of `hash` and fsyncs the shard directory.
core::Status installBlob(const fs::path& from, const fs::path& to) {
  if (auto st = ensureDurableDir(to.parent_path()); !st) return st;
  if (::rename(from.c_str(), to.c_str()) != 0) {
    const int err = errno;
    return makeError(ErrorCode::kIo, "cannot rename " + from.string() + " to " + to.string() + ": " +
                                         std::strerror(err));
  }
  return fsyncPath(to.parent_path(), true);
}

}  // namespace

core::Result<std::string> BlobStore::put(std::span<const std::uint8_t> bytes) {
  std::string hash = api::sha256Hex(bytes);
  const fs::path target = pathOf(hash);
  // Existing blob: not rewritten. A size mismatch (a blob truncated on disk)
  // is healed by writing it again; the rename replaces it atomically.
  struct stat existing{};
  if (::stat(target.c_str(), &existing) == 0 && S_ISREG(existing.st_mode) &&
      static_cast<std::size_t>(existing.st_size) == bytes.size()) {
    return hash;
  }

  const fs::path tmp_dir = root_ / "tmp";
  if (auto st = ensureDurableDirs(tmp_dir); !st) return st.error();
  const fs::path tmp = tmp_dir / (randomHex(16) + ".part");
  Fd fd(openRetrying(tmp, O_WRONLY | O_CREAT | O_EXCL, 0600));
  if (!fd.valid()) return ioError("cannot create", tmp, errno);
  auto fail = [&](Error e) -> core::Result<std::string> {
    fd.reset();
    ::unlink(tmp.c_str());
    return e;
  };
  if (auto st = writeAll(fd.get(), bytes.data(), bytes.size(), tmp); !st) return fail(st.error());
  if (::fsync(fd.get()) != 0) return fail(ioError("cannot fsync", tmp, errno));
  if (const int err = fd.close(); err != 0) return fail(ioError("cannot close", tmp, err));
  if (auto st = installBlob(tmp, target); !st) return fail(st.error());
  return hash;
}

core::Status BlobStore::probeWrite() {
  // Bigger than a page and a spool chunk, so a device that takes only small
  // writes (nearly full, a file-size limit) fails here as the real writes would.
  static const std::vector<std::uint8_t> kProbe(64 * 1024, 0x5a);
  const fs::path tmp_dir = root_ / "tmp";
  if (auto st = ensureDurableDirs(tmp_dir); !st) return st;
  const fs::path tmp = tmp_dir / (randomHex(16) + ".probe");
  Fd fd(openRetrying(tmp, O_WRONLY | O_CREAT | O_EXCL, 0600));
  if (!fd.valid()) return ioError("cannot create", tmp, errno);
  core::Status status = writeAll(fd.get(), kProbe.data(), kProbe.size(), tmp);
  if (status && ::fsync(fd.get()) != 0) status = ioError("cannot fsync", tmp, errno);
  if (const int err = fd.close(); status && err != 0) status = ioError("cannot close", tmp, err);
  if (::unlink(tmp.c_str()) != 0 && status) status = ioError("cannot remove", tmp, errno);
  return status;
}

core::Result<std::string> BlobStore::adopt(const fs::path& file) {
  auto hashed = sha256HexOfFile(file);
  if (!hashed) return hashed.error();
  std::string hash = std::move(*hashed);
  if (contains(hash)) {
    ::unlink(file.c_str());
    return hash;
  }
  if (auto st = ensureDurableDirs(root_); !st) return st.error();
  // The source may not have been fsynced by its writer.
  if (auto st = fsyncPath(file, false); !st) return st.error();
  const fs::path target = pathOf(hash);
  if (auto st = ensureDurableDir(target.parent_path()); !st) return st.error();
  if (::rename(file.c_str(), target.c_str()) == 0) {
    if (auto st = fsyncPath(target.parent_path(), true); !st) return st.error();
    return hash;
  }
  if (errno != EXDEV) {
    const int err = errno;
    return makeError(ErrorCode::kIo, "cannot rename " + file.string() + " to " + target.string() + ": " +
                                         std::strerror(err));
  }
  // Different filesystem: copy through put()'s temp + fsync + rename path.
  auto bytes = readWholeFile(file);
  if (!bytes) return bytes.error();
  auto copied = put(*bytes);
  if (!copied) return copied.error();
  if (*copied != hash) {
    return makeError(ErrorCode::kIo, "file " + file.string() + " changed while being adopted into the blob store");
  }
  ::unlink(file.c_str());
  return hash;
}

core::Result<std::vector<std::uint8_t>> BlobStore::read(const std::string& hash) const {
  if (!isHashHex(hash)) {
    return makeError(ErrorCode::kInvalidArgument, "not a blob hash (64 lower-case hex expected): '" + hash + "'");
  }
  const fs::path path = pathOf(hash);
  auto read_bytes = readWholeFile(path);
  if (!read_bytes) return read_bytes.error();
  std::vector<std::uint8_t> bytes = std::move(*read_bytes);
  const std::string actual = api::sha256Hex(bytes);
  if (actual != hash) {
    return makeError(ErrorCode::kIo, "blob " + path.string() + " is corrupted: content hashes to " + actual + " (" +
                                         std::to_string(bytes.size()) + " bytes)");
  }
  return bytes;
}

void BlobStore::remove(const std::string& hash) {
  if (!isHashHex(hash)) return;
  const fs::path path = pathOf(hash);
  if (::unlink(path.c_str()) == 0) (void)fsyncPath(path.parent_path(), true);
}

void BlobStore::removeTemporaries(std::chrono::seconds older_than) {
  std::error_code ec;
  const fs::path tmp_dir = root_ / "tmp";
  const auto cutoff = fs::file_time_type::clock::now() - older_than;
  for (fs::directory_iterator it(tmp_dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code rm_ec;
    const auto modified = fs::last_write_time(it->path(), rm_ec);
    if (rm_ec || (older_than.count() > 0 && modified > cutoff)) continue;
    fs::remove(it->path(), rm_ec);
  }
}

std::optional<std::string> secureRandomHex(std::size_t bytes) {
  std::vector<unsigned char> buf(bytes);
  if (RAND_bytes(buf.data(), static_cast<int>(buf.size())) != 1) return std::nullopt;
  return toHex(buf.data(), buf.size());
}

}  // namespace server
