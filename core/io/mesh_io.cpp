// Mesh file dispatch (extension, then magic bytes) and whole-file I/O.
// The atomic write follows the usual POSIX recipe (write a temp file in the
// same directory, fsync it, rename over the target, fsync the directory), so a
// reader never sees a half-written mesh and a crash leaves either the old or
// the new file.
#include "core/io/mesh_io.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <optional>
#include <utility>

namespace core {

// Defined in core/io/gltf_mesh_read.cpp (tinygltf stays in core/io/gltf_*.cpp). Like readGltf,
// but a .gltf may refer to external buffer files inside `base_dir`; it is not
// in mesh_io.h because only a path-based read has a directory to offer.
Result<LoadedMesh> readGltfWithBaseDir(std::span<const std::uint8_t> bytes, const std::string& label, bool binary,
                                       const std::filesystem::path& base_dir);

namespace {

std::string errnoText(int err) { return std::strerror(err); }

std::string lowerExtension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

std::optional<MeshFormat> formatFromExtension(const std::string& ext) {
  if (ext == ".glb") return MeshFormat::kGlb;
  if (ext == ".gltf") return MeshFormat::kGltf;
  if (ext == ".obj") return MeshFormat::kObj;
  if (ext == ".ply") return MeshFormat::kPly;
  return std::nullopt;
}

bool startsWith(std::span<const std::uint8_t> bytes, std::string_view prefix) {
  return bytes.size() >= prefix.size() && std::equal(prefix.begin(), prefix.end(), bytes.begin());
}

// Content sniffing for files whose extension says nothing. OBJ has no magic,
// so it is only ever chosen by extension.
std::optional<MeshFormat> formatFromMagic(std::span<const std::uint8_t> bytes) {
  if (startsWith(bytes, "glTF")) return MeshFormat::kGlb;
  if (startsWith(bytes, "ply\n") || startsWith(bytes, "ply\r\n")) return MeshFormat::kPly;
  // A JSON glTF starts with an object (after optional whitespace).
  for (const std::uint8_t b : bytes) {
    if (b == ' ' || b == '\t' || b == '\r' || b == '\n') continue;
    if (b == '{') return MeshFormat::kGltf;
    break;
  }
  return std::nullopt;
}

// Writes all of `bytes` to `fd`, retrying on partial writes and EINTR.
bool writeAll(int fd, std::span<const std::uint8_t> bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  return true;
}

// fsync of the directory makes the rename itself durable.
bool fsyncDirectory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  return ok;
}

}  // namespace

Result<LoadedMesh> readMeshFromMemory(std::span<const std::uint8_t> bytes, MeshFormat format, const std::string& label) {
  switch (format) {
    case MeshFormat::kGlb: return readGltf(bytes, label, /*binary=*/true);
    case MeshFormat::kGltf: return readGltf(bytes, label, /*binary=*/false);
    case MeshFormat::kObj: return readObj(bytes, label);
    case MeshFormat::kPly: return readPly(bytes, label);
  }
  return makeError(ErrorCode::kInvalidArgument, label + ": unknown mesh format");
}

namespace {

Result<MeshFormat> detectMeshFormat(std::span<const std::uint8_t> bytes, const std::filesystem::path& file_name,
                                    const std::string& label) {
  std::optional<MeshFormat> format = formatFromExtension(lowerExtension(file_name));
  if (!format) format = formatFromMagic(bytes);
  if (!format) {
    return makeError(ErrorCode::kUnsupported,
                     label + ": unrecognised mesh format (expected .glb, .gltf, .obj or .ply, and the content is not "
                             "binary glTF, glTF JSON or PLY)");
  }
  return *format;
}

}  // namespace

Result<LoadedMesh> readMeshFromMemory(std::span<const std::uint8_t> bytes, const std::filesystem::path& file_name,
                                      const std::string& label) {
  auto format = detectMeshFormat(bytes, file_name, label);
  if (!format) return format.error();
  return readMeshFromMemory(bytes, *format, label);
}

Result<LoadedMesh> readMesh(const std::filesystem::path& path) {
  const std::string label = path.filename().string();
  auto file = MappedFile::open(path);
  if (!file) return file.error();
  const std::span<const std::uint8_t> bytes = file->bytes();
  auto format = detectMeshFormat(bytes, path, label);
  if (!format) return format.error();
  // A glTF read from disk may use buffer files beside it.
  if (*format == MeshFormat::kGltf || *format == MeshFormat::kGlb) {
    return readGltfWithBaseDir(bytes, label, /*binary=*/*format == MeshFormat::kGlb, path.parent_path());
  }
  return readMeshFromMemory(bytes, *format, label);
}

Result<MappedFile> MappedFile::open(const std::filesystem::path& path) {
  // Below this a read costs no more than a mapping.
  constexpr off_t kMapFrom = off_t{1} << 20;
  MappedFile file;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    return makeError(ErrorCode::kIo, path.string() + ": cannot open for reading: " + errnoText(err));
  }
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size >= kMapFrom) {
    void* mapping = ::mmap(nullptr, static_cast<std::size_t>(st.st_size), PROT_READ, MAP_PRIVATE, fd, 0);
    ::close(fd);
    if (mapping != MAP_FAILED) {
      // Parsers read front to back.
      ::madvise(mapping, static_cast<std::size_t>(st.st_size), MADV_SEQUENTIAL);
      file.mapping_ = mapping;
      file.data_ = static_cast<const std::uint8_t*>(mapping);
      file.size_ = static_cast<std::size_t>(st.st_size);
      return file;
    }
  } else {
    ::close(fd);
  }
  auto bytes = readFileBytes(path);
  if (!bytes) return bytes.error();
  file.read_ = std::move(*bytes);
  file.data_ = file.read_.data();
  file.size_ = file.read_.size();
  return file;
}

MappedFile::MappedFile(MappedFile&& other) noexcept { *this = std::move(other); }

MappedFile& MappedFile::operator=(MappedFile&& other) noexcept {
  if (this == &other) return *this;
  if (mapping_ != nullptr) ::munmap(mapping_, size_);
  mapping_ = std::exchange(other.mapping_, nullptr);
  size_ = std::exchange(other.size_, 0);
  read_ = std::move(other.read_);
  data_ = mapping_ != nullptr ? static_cast<const std::uint8_t*>(mapping_) : read_.data();
  other.data_ = nullptr;
  return *this;
}

MappedFile::~MappedFile() {
  if (mapping_ != nullptr) ::munmap(mapping_, size_);
}

Result<std::vector<std::uint8_t>> readFileBytes(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    return makeError(ErrorCode::kIo, path.string() + ": cannot open for reading: " + errnoText(err));
  }
  std::vector<std::uint8_t> bytes;
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
    bytes.reserve(static_cast<std::size_t>(st.st_size));
  }
  std::uint8_t chunk[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, chunk, sizeof(chunk));
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      return makeError(ErrorCode::kIo, path.string() + ": read failed: " + errnoText(err));
    }
    bytes.insert(bytes.end(), chunk, chunk + n);
  }
  ::close(fd);
  return bytes;
}

Status writeFileBytes(const std::filesystem::path& path, std::span<const std::uint8_t> bytes) {
  // pid + per-process counter: concurrent writers (threads or processes) of the
  // same target never share a temp file.
  static std::atomic<unsigned long long> counter{0};
  std::filesystem::path tmp = path;
  tmp += ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter.fetch_add(1));

  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    return makeError(ErrorCode::kIo, path.string() + ": cannot create temporary file " + tmp.string() + ": " +
                                         errnoText(err));
  }
  auto fail = [&](const std::string& what, int err) -> Status {
    ::unlink(tmp.c_str());
    return makeError(ErrorCode::kIo, path.string() + ": " + what + ": " + errnoText(err));
  };
  if (!writeAll(fd, bytes)) {
    const int err = errno;
    ::close(fd);
    return fail("write failed", err);
  }
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    return fail("fsync failed", err);
  }
  if (::close(fd) != 0) {
    const int err = errno;
    return fail("close failed", err);
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    return fail("rename from " + tmp.string() + " failed", err);
  }
  if (!fsyncDirectory(path.parent_path())) {
    const int err = errno;
    return makeError(ErrorCode::kIo, path.string() + ": written, but fsync of its directory failed: " + errnoText(err));
  }
  return Ok{};
}

}  // namespace core
