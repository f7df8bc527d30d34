// Reading and writing meshes: glTF/GLB (core/io/gltf_*.cpp), OBJ (core/io/obj_io.cpp),
// PLY (core/io/ply_io.cpp). Every reader returns a validated core::Mesh or an Error
// whose message starts with the file label and names the defect.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/geometry/mesh.h"

namespace core {

enum class MeshFormat { kGlb, kGltf, kObj, kPly };

// What a reader did to turn the file into a Mesh, for diagnostics.
struct MeshReadReport {
  MeshFormat format = MeshFormat::kGlb;
  std::string chosen_mesh;               // glTF: which mesh/node was taken and why ("first skinned", "largest")
  int meshes_in_file = 0;                // glTF meshes (primitives counted once per mesh)
  int polygons_triangulated = 0;         // input faces with more than 3 corners, fan-triangulated
  int degenerate_triangles = 0;          // kept in the mesh but skipped by the algorithms
  bool normals_computed = false;         // the file had no normals; area-weighted ones were computed
  bool point_cloud = false;              // no faces in the file
  std::vector<std::string> warnings;     // anything else a TD should know
};

struct LoadedMesh {
  Mesh mesh;
  MeshReadReport report;
};

// Chooses the reader from the extension (.glb .gltf .obj .ply, case-insensitive),
// falling back to the content's magic bytes. `label` defaults to the file name.
Result<LoadedMesh> readMesh(const std::filesystem::path& path);

// Reads from memory; `format` is required because there is no file name. `label`
// names the data in error messages (for example the upload's field name).
Result<LoadedMesh> readMeshFromMemory(std::span<const std::uint8_t> bytes, MeshFormat format, const std::string& label);
// The same with the format chosen as readMesh does: from `file_name`'s
// extension (an upload's file name), else from the content's magic bytes.
Result<LoadedMesh> readMeshFromMemory(std::span<const std::uint8_t> bytes, const std::filesystem::path& file_name,
                                      const std::string& label);

// Format readers (also used by readMesh). A glTF node transform is applied to
// positions and normals. The mesh chosen from a multi-mesh glTF is the first
// skinned one, else the one with most triangles; the choice is reported.
Result<LoadedMesh> readGltf(std::span<const std::uint8_t> bytes, const std::string& label, bool binary);
Result<LoadedMesh> readObj(std::span<const std::uint8_t> bytes, const std::string& label);
Result<LoadedMesh> readPly(std::span<const std::uint8_t> bytes, const std::string& label);

// A single-mesh GLB (POSITION, NORMAL when present, TEXCOORD_0 when present,
// _REGION when the mesh has region labels, uint32 indices) that passes the
// Khronos validator. Deterministic bytes.
Result<std::vector<std::uint8_t>> encodeMeshGlb(const Mesh& mesh);
Status writeMeshGlb(const Mesh& mesh, const std::filesystem::path& path);

// Whole-file read and atomic write (temp file + rename) used by all file formats.
Result<std::vector<std::uint8_t>> readFileBytes(const std::filesystem::path& path);

// A large input read in place: a regular file is mapped read-only, so its
// bytes come straight from the page cache instead of being copied into fresh
// memory (for a 7.8 MB rig, 4 ms of a one-off CLI run); anything else (a
// pipe, a small file) is read with readFileBytes. Used by readMesh and
// readRig, which only parse the bytes. As with any mapped read, a file cut
// short by another process while it is parsed would fault (SIGBUS); the
// service parses request bodies from memory, never through a mapping.
// Move-only; unmaps on destruction.
class MappedFile {
 public:
  static Result<MappedFile> open(const std::filesystem::path& path);
  MappedFile(MappedFile&& other) noexcept;
  MappedFile& operator=(MappedFile&& other) noexcept;
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  ~MappedFile();
  std::span<const std::uint8_t> bytes() const { return {data_, size_}; }

 private:
  MappedFile() = default;
  void* mapping_ = nullptr;  // nullptr: the bytes live in `read_`
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
  std::vector<std::uint8_t> read_;
};
Status writeFileBytes(const std::filesystem::path& path, std::span<const std::uint8_t> bytes);

}  // namespace core
