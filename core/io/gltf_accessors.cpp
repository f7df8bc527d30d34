// glTF accessors decoded with every range checked (overflow-safe): views,
// strides, sparse overrides, normalised integers. Used by every reader.

#include "core/io/gltf_model.h"

namespace core::gltf {

namespace {

// ---------------------------------------------------------------------------
// Accessor reading (bounds-checked; also for skins, morphs and animations)

int componentSize(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

// Rows and columns of one element (vectors are one column).
std::pair<int, int> elementShape(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return {1, 1};
    case TINYGLTF_TYPE_VEC2: return {2, 1};
    case TINYGLTF_TYPE_VEC3: return {3, 1};
    case TINYGLTF_TYPE_VEC4: return {4, 1};
    case TINYGLTF_TYPE_MAT2: return {2, 2};
    case TINYGLTF_TYPE_MAT3: return {3, 3};
    case TINYGLTF_TYPE_MAT4: return {4, 4};
    default: return {0, 0};
  }
}

}  // namespace

int typeComponents(int type) { return elementShape(type).first * elementShape(type).second; }

namespace {

ElementLayout elementLayout(int type, int component_type) {
  const auto [rows, columns] = elementShape(type);
  ElementLayout layout;
  layout.rows = rows;
  layout.columns = columns;
  layout.component_size = static_cast<std::size_t>(componentSize(component_type));
  layout.column_stride = layout.component_size * static_cast<std::size_t>(rows);
  if (columns > 1) layout.column_stride = (layout.column_stride + 3) / 4 * 4;
  layout.size = layout.column_stride * static_cast<std::size_t>(columns);
  return layout;
}

double decodeComponent(const std::uint8_t* p, int component_type, bool normalized) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const auto v = static_cast<std::int8_t>(p[0]);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      const auto v = static_cast<std::int16_t>(static_cast<std::uint16_t>(p[0] | p[1] << 8));
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      const auto v = static_cast<std::uint16_t>(p[0] | p[1] << 8);
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_INT: return static_cast<std::int32_t>(readLe32(p));
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return readLe32(p);
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return std::bit_cast<float>(readLe32(p));
    default: return 0.0;
  }
}

void decodeElement(const std::uint8_t* src, const ElementLayout& layout, int component_type, bool normalized,
                   double* dst, std::size_t component_stride) {
  for (int c = 0; c < layout.columns; ++c) {
    for (int r = 0; r < layout.rows; ++r) {
      *dst = decodeComponent(src + static_cast<std::size_t>(c) * layout.column_stride +
                                 static_cast<std::size_t>(r) * layout.component_size,
                             component_type, normalized);
      dst += component_stride;
    }
  }
}

// Bytes needed by `count` elements of `element_size` at `stride`, or nullopt
// on overflow.
std::optional<std::size_t> spanBytes(std::size_t count, std::size_t stride, std::size_t element_size) {
  if (count == 0) return std::size_t{0};
  std::size_t bytes = 0;
  if (__builtin_mul_overflow(count - 1, stride, &bytes) || __builtin_add_overflow(bytes, element_size, &bytes)) {
    return std::nullopt;
  }
  return bytes;
}

// Returns the data of `view_index` after checking that [offset, offset+needed)
// lies inside the bufferView and the bufferView inside its buffer. `what`
// names the reader in messages ("accessor 3 (POSITION)").
Result<const std::uint8_t*> viewRange(const tinygltf::Model& model, int view_index, std::size_t offset,
                                      std::optional<std::size_t> needed, const std::string& what,
                                      const std::string& label) {
  if (view_index < 0 || static_cast<std::size_t>(view_index) >= model.bufferViews.size()) {
    return parseError(label, what + " refers to bufferView " + std::to_string(view_index) + " but the file has " +
                                 std::to_string(model.bufferViews.size()));
  }
  const tinygltf::BufferView& view = model.bufferViews[static_cast<std::size_t>(view_index)];
  if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= model.buffers.size()) {
    return parseError(label, "bufferView " + std::to_string(view_index) + " (used by " + what +
                                 ") refers to buffer " + std::to_string(view.buffer) + " but the file has " +
                                 std::to_string(model.buffers.size()));
  }
  const std::vector<unsigned char>& data = model.buffers[static_cast<std::size_t>(view.buffer)].data;
  const std::string view_name = "bufferView " + std::to_string(view_index);
  if (!needed || offset > view.byteLength || *needed > view.byteLength - offset) {
    return parseError(label, what + " reads past the end of " + view_name + " (needs " +
                                 (needed ? std::to_string(*needed) : std::string("more than 2^64")) +
                                 " bytes at offset " + std::to_string(offset) + ", " + view_name + " has " +
                                 std::to_string(view.byteLength) + ")");
  }
  if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset) {
    return parseError(label, what + " reads past the end of buffer " + std::to_string(view.buffer) + " (needs " +
                                 std::to_string(view.byteLength) + " bytes at offset " +
                                 std::to_string(view.byteOffset) + ", buffer has " + std::to_string(data.size()) +
                                 ")");
  }
  return data.data() + view.byteOffset + offset;
}

}  // namespace

Result<CheckedAccessor> checkAccessor(const tinygltf::Model& model, int index, const std::string& role,
                                      const std::string& label) {
  CheckedAccessor out;
  out.what = "accessor " + std::to_string(index) + " (" + role + ")";
  const std::string& what = out.what;
  if (index < 0 || static_cast<std::size_t>(index) >= model.accessors.size()) {
    return parseError(label, role + " refers to accessor " + std::to_string(index) + " but the file has " +
                                 std::to_string(model.accessors.size()));
  }
  const tinygltf::Accessor& accessor = model.accessors[static_cast<std::size_t>(index)];
  out.layout = elementLayout(accessor.type, accessor.componentType);
  if (out.layout.rows == 0) return parseError(label, what + " has an invalid type");
  if (out.layout.component_size == 0) {
    return parseError(label, what + " has unsupported componentType " + std::to_string(accessor.componentType));
  }
  out.count = accessor.count;
  out.components = out.layout.rows * out.layout.columns;
  out.component_type = accessor.componentType;
  out.normalized = accessor.normalized;
  if (accessor.bufferView < 0) {
    if (accessor.count > kMaxImplicitAccessorCount) {
      return parseError(label, what + " has no bufferView and claims " + std::to_string(accessor.count) +
                                   " elements (more than the " + std::to_string(kMaxImplicitAccessorCount) +
                                   " supported)");
    }
  } else {
    const tinygltf::BufferView* view = static_cast<std::size_t>(accessor.bufferView) < model.bufferViews.size()
                                           ? &model.bufferViews[static_cast<std::size_t>(accessor.bufferView)]
                                           : nullptr;
    out.stride = view && view->byteStride != 0 ? view->byteStride : out.layout.size;
    if (out.stride < out.layout.size) {
      return parseError(label, what + " has elements of " + std::to_string(out.layout.size) +
                                   " bytes but bufferView byteStride " + std::to_string(out.stride));
    }
    // This bounds count by the buffer size, so a destination sized by it is
    // at most a few times the file size.
    auto data = viewRange(model, accessor.bufferView, accessor.byteOffset,
                          spanBytes(accessor.count, out.stride, out.layout.size), what, label);
    if (!data) return data.error();
    out.data = *data;
  }
  if (!accessor.sparse.isSparse) return out;

  const auto& sparse = accessor.sparse;
  if (sparse.count < 0 || static_cast<std::size_t>(sparse.count) > accessor.count) {
    return parseError(label, what + " has a sparse count of " + std::to_string(sparse.count) + " for " +
                                 std::to_string(accessor.count) + " elements");
  }
  if (sparse.indices.byteOffset < 0 || sparse.values.byteOffset < 0) {
    return parseError(label, what + " has a negative sparse byteOffset");
  }
  out.sparse_count = static_cast<std::size_t>(sparse.count);
  out.sparse_index_type = sparse.indices.componentType;
  if (out.sparse_index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
      out.sparse_index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      out.sparse_index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
    return parseError(label, what + " has sparse indices of invalid componentType " +
                                 std::to_string(out.sparse_index_type));
  }
  const std::size_t index_size = static_cast<std::size_t>(componentSize(out.sparse_index_type));
  auto indices = viewRange(model, sparse.indices.bufferView, static_cast<std::size_t>(sparse.indices.byteOffset),
                           spanBytes(out.sparse_count, index_size, index_size), what + " sparse indices", label);
  if (!indices) return indices.error();
  auto values = viewRange(model, sparse.values.bufferView, static_cast<std::size_t>(sparse.values.byteOffset),
                          spanBytes(out.sparse_count, out.layout.size, out.layout.size), what + " sparse values",
                          label);
  if (!values) return values.error();
  out.sparse_indices = *indices;
  out.sparse_values = *values;
  return out;
}

Status decodeAccessor(const CheckedAccessor& a, DecodeDestination dst, const std::string& label) {
  const std::size_t components = static_cast<std::size_t>(a.components);
  if (a.data == nullptr) {
    for (std::size_t i = 0; i < a.count; ++i) {
      for (std::size_t c = 0; c < components; ++c) dst.data[i * dst.element_stride + c * dst.component_stride] = 0.0;
    }
  } else if (a.component_type == TINYGLTF_COMPONENT_TYPE_FLOAT) {
    // The common case (positions, normals, morph deltas, weights, keys),
    // without a component-type switch per value. Float components are 4-byte
    // aligned, so a matrix's columns follow each other without padding.
    for (std::size_t i = 0; i < a.count; ++i) {
      const std::uint8_t* src = a.data + i * a.stride;
      double* out = dst.data + i * dst.element_stride;
      for (std::size_t c = 0; c < components; ++c) {
        out[c * dst.component_stride] = std::bit_cast<float>(readLe32(src + 4 * c));
      }
    }
  } else {
    for (std::size_t i = 0; i < a.count; ++i) {
      decodeElement(a.data + i * a.stride, a.layout, a.component_type, a.normalized,
                    dst.data + i * dst.element_stride, dst.component_stride);
    }
  }
  const std::size_t index_size = static_cast<std::size_t>(componentSize(a.sparse_index_type));
  for (std::size_t i = 0; i < a.sparse_count; ++i) {
    const double index = decodeComponent(a.sparse_indices + i * index_size, a.sparse_index_type, false);
    if (index >= static_cast<double>(a.count)) {
      return parseError(label, a.what + " sparse index " + std::to_string(i) + " is " +
                                   std::to_string(static_cast<std::uint64_t>(index)) + " but the accessor has " +
                                   std::to_string(a.count) + " elements");
    }
    decodeElement(a.sparse_values + i * a.layout.size, a.layout, a.component_type, a.normalized,
                  dst.data + static_cast<std::size_t>(index) * dst.element_stride, dst.component_stride);
  }
  return Ok{};
}

Result<AccessorValues> readAccessor(const tinygltf::Model& model, int index, const std::string& role,
                                    const std::string& label) {
  auto checked = checkAccessor(model, index, role, label);
  if (!checked) return checked.error();
  AccessorValues out;
  out.count = checked->count;
  out.components = checked->components;
  out.values.resize(out.count * static_cast<std::size_t>(out.components));
  if (auto ok = decodeAccessor(*checked, {out.values.data(), static_cast<std::size_t>(out.components), 1}, label);
      !ok) {
    return ok.error();
  }
  return out;
}

}  // namespace core::gltf
