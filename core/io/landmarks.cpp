// Landmarks JSON reading/writing and resolution on a mesh. nlohmann::json is
// used privately here (file format edge); nothing JSON leaves this file.
#include "core/io/landmarks.h"

#include <cmath>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/geometry/closest_point.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/solve/tps.h"

namespace core {

int LandmarkSet::indexOf(std::string_view name) const {
  for (std::size_t i = 0; i < landmarks.size(); ++i) {
    if (landmarks[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

namespace {

std::string entryLabel(const std::string& label, std::size_t i, const std::string& name) {
  std::string s = label + ": landmarks[" + std::to_string(i) + "]";
  if (!name.empty()) s += " ('" + name + "')";
  return s;
}

Result<Eigen::Vector3d> readVec3(const nlohmann::json& value, const std::string& where, const char* field) {
  if (!value.is_array() || value.size() != 3) {
    return makeError(ErrorCode::kInvalidLandmarks, where + ": '" + field + "' must be an array of 3 numbers");
  }
  Eigen::Vector3d v;
  for (int k = 0; k < 3; ++k) {
    if (!value[static_cast<std::size_t>(k)].is_number()) {
      return makeError(ErrorCode::kInvalidLandmarks, where + ": '" + field + "' must be an array of 3 numbers");
    }
    v(k) = value[static_cast<std::size_t>(k)].get<double>();
  }
  if (!v.allFinite()) return makeError(ErrorCode::kInvalidLandmarks, where + ": '" + field + "' is not finite");
  return v;
}

}  // namespace

Result<LandmarkSet> parseLandmarks(std::string_view json_text, const std::string& label) {
  auto parsed = parseJsonText(json_text, label);
  if (!parsed) return parsed.error();
  const nlohmann::json& doc = *parsed;
  if (!doc.is_object() || !doc.contains("landmarks") || !doc["landmarks"].is_array()) {
    return makeError(ErrorCode::kInvalidLandmarks, label + ": expected an object with a 'landmarks' array");
  }
  LandmarkSet set;
  std::set<std::string> seen;
  const auto& entries = doc["landmarks"];
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const auto& e = entries[i];
    if (!e.is_object()) return makeError(ErrorCode::kInvalidLandmarks, entryLabel(label, i, "") + ": not an object");
    if (!e.contains("name") || !e["name"].is_string() || e["name"].get<std::string>().empty()) {
      return makeError(ErrorCode::kInvalidLandmarks, entryLabel(label, i, "") + ": missing a non-empty string 'name'");
    }
    Landmark lm;
    lm.name = e["name"].get<std::string>();
    const std::string where = entryLabel(label, i, lm.name);
    if (!seen.insert(lm.name).second) {
      return makeError(ErrorCode::kInvalidLandmarks, where + ": duplicate name '" + lm.name + "'");
    }
    const int kinds = int(e.contains("vertex")) + int(e.contains("position")) + int(e.contains("face"));
    if (kinds != 1) {
      return makeError(ErrorCode::kInvalidLandmarks,
                       where + ": needs exactly one of 'vertex', 'position' or 'face'+'barycentric'");
    }
    if (e.contains("vertex")) {
      if (!e["vertex"].is_number_integer() || e["vertex"].get<long long>() < 0 ||
          e["vertex"].get<long long>() > std::numeric_limits<int>::max()) {
        return makeError(ErrorCode::kInvalidLandmarks, where + ": 'vertex' must be a non-negative integer");
      }
      lm.kind = LandmarkKind::kVertex;
      lm.vertex = static_cast<int>(e["vertex"].get<long long>());
    } else if (e.contains("position")) {
      auto p = readVec3(e["position"], where, "position");
      if (!p) return p.error();
      lm.kind = LandmarkKind::kPosition;
      lm.position = *p;
    } else {
      if (!e["face"].is_number_integer() || e["face"].get<long long>() < 0 ||
          e["face"].get<long long>() > std::numeric_limits<int>::max()) {
        return makeError(ErrorCode::kInvalidLandmarks, where + ": 'face' must be a non-negative integer");
      }
      if (!e.contains("barycentric")) {
        return makeError(ErrorCode::kInvalidLandmarks, where + ": 'face' needs 'barycentric' [a,b,c]");
      }
      auto b = readVec3(e["barycentric"], where, "barycentric");
      if (!b) return b.error();
      const double sum = b->sum();
      if (b->minCoeff() < -1e-6 || std::abs(sum - 1.0) > 1e-3) {
        std::ostringstream msg;
        msg << where << ": 'barycentric' must be non-negative and sum to 1 (got " << (*b)(0) << ", " << (*b)(1)
            << ", " << (*b)(2) << ")";
        return makeError(ErrorCode::kInvalidLandmarks, msg.str());
      }
      lm.kind = LandmarkKind::kFace;
      lm.face = static_cast<int>(e["face"].get<long long>());
      lm.barycentric = b->cwiseMax(0.0) / b->cwiseMax(0.0).sum();
    }
    set.landmarks.push_back(std::move(lm));
  }
  return set;
}

Result<LandmarkSet> readLandmarks(const std::filesystem::path& path) {
  auto bytes = readFileBytes(path);
  if (!bytes) return bytes.error();
  const std::string text(bytes->begin(), bytes->end());
  return parseLandmarks(text, path.filename().string());
}

std::string formatLandmarks(const LandmarkSet& set) {
  nlohmann::ordered_json doc;
  doc["landmarks"] = nlohmann::ordered_json::array();
  for (const auto& lm : set.landmarks) {
    nlohmann::ordered_json e;
    e["name"] = lm.name;
    switch (lm.kind) {
      case LandmarkKind::kVertex: e["vertex"] = lm.vertex; break;
      case LandmarkKind::kPosition: e["position"] = {lm.position(0), lm.position(1), lm.position(2)}; break;
      case LandmarkKind::kFace:
        e["face"] = lm.face;
        e["barycentric"] = {lm.barycentric(0), lm.barycentric(1), lm.barycentric(2)};
        break;
    }
    doc["landmarks"].push_back(std::move(e));
  }
  return doc.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

std::vector<int> landmarkVertices(const LandmarkSet& set, const Mesh& mesh, const Eigen::MatrixX3d& positions,
                                  const ClosestPointIndex* index) {
  auto largestCorner = [&](int face, const Eigen::Vector3d& barycentric) {
    Eigen::Index corner = 0;
    barycentric.maxCoeff(&corner);
    return mesh.triangles(face, corner);
  };
  std::vector<int> vertices;
  vertices.reserve(set.landmarks.size());
  for (std::size_t l = 0; l < set.landmarks.size(); ++l) {
    const Landmark& landmark = set.landmarks[l];
    const Eigen::RowVector3d at = positions.row(static_cast<Eigen::Index>(l));
    int v = landmark.vertex;
    if (landmark.kind == LandmarkKind::kFace) {
      v = largestCorner(landmark.face, landmark.barycentric);
    } else if (landmark.kind == LandmarkKind::kPosition && index) {
      const SurfacePoint sp = index->closestPoint(at.transpose());
      v = sp.found() ? largestCorner(sp.face, sp.barycentric) : -1;
    } else if (landmark.kind == LandmarkKind::kPosition) {
      (mesh.positions.rowwise() - at).rowwise().squaredNorm().minCoeff(&v);
    }
    vertices.push_back(v);
  }
  return vertices;
}

Result<Eigen::MatrixX3d> resolveLandmarks(const LandmarkSet& set, const Mesh& mesh, const std::string& label,
                                          const ClosestPointIndex* index, const ResolveLandmarksOptions& options) {
  Eigen::MatrixX3d out(static_cast<Eigen::Index>(set.landmarks.size()), 3);
  const double diag = boundingBoxDiagonal(mesh.positions);
  for (std::size_t i = 0; i < set.landmarks.size(); ++i) {
    const Landmark& lm = set.landmarks[i];
    const std::string where = entryLabel(label, i, lm.name);
    switch (lm.kind) {
      case LandmarkKind::kVertex:
        if (lm.vertex >= mesh.vertexCount()) {
          return makeError(ErrorCode::kInvalidLandmarks, where + ": vertex " + std::to_string(lm.vertex) +
                                                             " is out of range (mesh has " +
                                                             std::to_string(mesh.vertexCount()) + " vertices)");
        }
        out.row(static_cast<Eigen::Index>(i)) = mesh.positions.row(lm.vertex);
        break;
      case LandmarkKind::kFace: {
        if (lm.face >= mesh.triangleCount()) {
          return makeError(ErrorCode::kInvalidLandmarks, where + ": face " + std::to_string(lm.face) +
                                                             " is out of range (mesh has " +
                                                             std::to_string(mesh.triangleCount()) + " triangles)");
        }
        out.row(static_cast<Eigen::Index>(i)) = interpolateOnFace(mesh.positions, mesh.triangles, lm.face, lm.barycentric);
        break;
      }
      case LandmarkKind::kPosition: {
        double sq = std::numeric_limits<double>::infinity();
        if (mesh.triangleCount() == 0) {
          sq = (mesh.positions.rowwise() - lm.position.transpose()).rowwise().squaredNorm().minCoeff();
        } else if (index) {
          sq = index->closestPoint(lm.position).sq_distance;
        } else {
          for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
            const auto cp = closestPointOnTriangle(lm.position, mesh.positions.row(mesh.triangles(f, 0)),
                                                   mesh.positions.row(mesh.triangles(f, 1)),
                                                   mesh.positions.row(mesh.triangles(f, 2)));
            sq = std::min(sq, cp.sq_distance);
          }
        }
        const double dist = std::sqrt(sq);
        if (!(dist <= options.max_off_surface * diag)) {
          std::ostringstream msg;
          msg << where << ": position is off the mesh (" << dist << " from the surface, limit "
              << options.max_off_surface * diag << " = " << options.max_off_surface << " x bbox diagonal)";
          return makeError(ErrorCode::kInvalidLandmarks, msg.str());
        }
        out.row(static_cast<Eigen::Index>(i)) = lm.position.transpose();
        break;
      }
    }
  }
  return out;
}

Status checkSharedLandmarkNames(const LandmarkSet& source, const LandmarkSet& target, const std::string& target_label) {
  std::vector<std::string> unknown;
  int shared = 0;
  for (const auto& lm : target.landmarks) {
    if (source.indexOf(lm.name) < 0) {
      unknown.push_back(lm.name);
    } else {
      ++shared;
    }
  }
  if (!unknown.empty()) {
    std::string list;
    for (std::size_t i = 0; i < unknown.size() && i < 10; ++i) list += (i ? ", '" : "'") + unknown[i] + "'";
    if (unknown.size() > 10) list += ", ...";
    return makeError(ErrorCode::kInvalidLandmarks, target_label + ": " + std::to_string(unknown.size()) +
                                                       " landmark name(s) not among the rig's landmarks: " + list);
  }
  if (shared < 4) {
    return makeError(ErrorCode::kInvalidLandmarks, target_label + ": only " + std::to_string(shared) +
                                                       " landmark name(s) shared with the rig; at least 4 "
                                                       "non-coplanar ones are needed");
  }
  return Ok{};
}

Result<LandmarkPairs> pairLandmarks(const LandmarkSet& source, const Eigen::MatrixX3d& source_positions,
                                    const LandmarkSet& target, const Eigen::MatrixX3d& target_positions,
                                    const std::string& target_label) {
  if (auto ok = checkSharedLandmarkNames(source, target, target_label); !ok) return ok.error();
  LandmarkPairs pairs;
  std::vector<std::pair<int, int>> index;
  for (std::size_t s = 0; s < source.landmarks.size(); ++s) {
    const int t = target.indexOf(source.landmarks[s].name);
    if (t >= 0) index.emplace_back(static_cast<int>(s), t);
  }
  pairs.source.resize(static_cast<Eigen::Index>(index.size()), 3);
  pairs.target.resize(static_cast<Eigen::Index>(index.size()), 3);
  for (std::size_t k = 0; k < index.size(); ++k) {
    pairs.names.push_back(source.landmarks[static_cast<std::size_t>(index[k].first)].name);
    pairs.source.row(static_cast<Eigen::Index>(k)) = source_positions.row(index[k].first);
    pairs.target.row(static_cast<Eigen::Index>(k)) = target_positions.row(index[k].second);
  }
  return pairs;
}

Status checkWarpTarget(const LandmarkSet& source, const Mesh& target, const LandmarkSet& target_landmarks,
                       const Eigen::MatrixX3d& target_positions, const std::string& target_label,
                       const TpsOptions& landmark_tps) {
  if (auto ok = validateSurfaceMesh(target, target_label); !ok) return ok;
  if (auto ok = checkSharedLandmarkNames(source, target_landmarks, target_label); !ok) return ok;
  std::vector<std::string> names;
  std::vector<Eigen::Index> rows;
  for (const Landmark& lm : source.landmarks) {
    const int t = target_landmarks.indexOf(lm.name);
    if (t < 0) continue;
    names.push_back(lm.name);
    rows.push_back(t);
  }
  Eigen::MatrixX3d shared(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t k = 0; k < rows.size(); ++k) shared.row(static_cast<Eigen::Index>(k)) = target_positions.row(rows[k]);
  if (auto ok = checkTpsCentres(shared, landmark_tps, names); !ok) {
    return Error{ok.error().code, target_label + ": " + ok.error().message};
  }
  return Ok{};
}

}  // namespace core
