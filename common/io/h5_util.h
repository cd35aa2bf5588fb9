// Small HDF5 (serial, H5Cpp) helpers shared by the project's HDF5 files (map.h5, training
// checkpoints): fixed little-endian file types, untimed datasets and groups (the same content
// gives the same bytes), attributes, and a validating Reader whose errors read
// "<file>: <field>: <reason>", and write_h5_atomically. Never linked by infer.
#pragma once

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <type_traits>
#include <vector>

#include <H5Cpp.h>

#include "common/error.h"
#include "common/file_io.h"

namespace lmb::h5 {

// Column types: the HDF5 memory type and the type class a stored dataset must have.
template <typename T>
const H5::PredType& mem_type();
template <>
inline const H5::PredType& mem_type<double>() {
  return H5::PredType::NATIVE_DOUBLE;
}
template <>
inline const H5::PredType& mem_type<float>() {
  return H5::PredType::NATIVE_FLOAT;
}
template <>
inline const H5::PredType& mem_type<int32_t>() {
  return H5::PredType::NATIVE_INT32;
}
template <>
inline const H5::PredType& mem_type<int64_t>() {
  return H5::PredType::NATIVE_INT64;
}
template <>
inline const H5::PredType& mem_type<uint8_t>() {
  return H5::PredType::NATIVE_UINT8;
}

// The file's on-disk types (little endian, fixed size), so files are the same on every machine.
template <typename T>
const H5::PredType& file_type();
template <>
inline const H5::PredType& file_type<double>() {
  return H5::PredType::IEEE_F64LE;
}
template <>
inline const H5::PredType& file_type<float>() {
  return H5::PredType::IEEE_F32LE;
}
template <>
inline const H5::PredType& file_type<int32_t>() {
  return H5::PredType::STD_I32LE;
}
template <>
inline const H5::PredType& file_type<int64_t>() {
  return H5::PredType::STD_I64LE;
}
template <>
inline const H5::PredType& file_type<uint8_t>() {
  return H5::PredType::STD_U8LE;
}

// Dataset creation without modification times, so that the same map gives the same bytes.
inline H5::DSetCreatPropList untimed_dataset() {
  H5::DSetCreatPropList plist;
  H5Pset_obj_track_times(plist.getId(), false);
  return plist;
}

inline H5::Group create_untimed_group(H5::H5File& file, const char* name) {
  const hid_t gcpl = H5Pcreate(H5P_GROUP_CREATE);
  H5Pset_obj_track_times(gcpl, false);
  const hid_t id = H5Gcreate2(file.getId(), name, H5P_DEFAULT, gcpl, H5P_DEFAULT);
  H5Pclose(gcpl);
  if (id < 0) throw H5::GroupIException("create_untimed_group", std::string("cannot create group ") + name);
  H5::Group group(id);
  H5Gclose(id);  // H5::Group(id) took its own reference
  return group;
}

template <typename T>
void write_column(H5::Group& group, const char* name, const std::vector<T>& data, hsize_t rows, hsize_t cols = 0) {
  const int rank = cols == 0 ? 1 : 2;
  const hsize_t dims[2] = {rows, cols};
  H5::DataSpace space(rank, dims);
  H5::DataSet ds = group.createDataSet(name, file_type<T>(), space, untimed_dataset());
  if (!data.empty()) ds.write(data.data(), mem_type<T>());
  // Closed here, not by the destructor: H5Dclose flushes, and a failure there (a full disk) must
  // throw; HDF5's C++ destructors print it and carry on (found by scripts/fault_inject.sh).
  ds.close();
}

inline void write_string_attribute(H5::H5Object& obj, const char* name, const std::string& value) {
  H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
  H5::Attribute attr = obj.createAttribute(name, type, H5::DataSpace(H5S_SCALAR));
  attr.write(type, value);
}

template <typename T>
void write_scalar_attribute(H5::H5Object& obj, const char* name, T value) {
  H5::Attribute attr = obj.createAttribute(name, file_type<T>(), H5::DataSpace(H5S_SCALAR));
  attr.write(mem_type<T>(), &value);
}

inline void write_int_attribute(H5::H5Object& obj, const char* name, int32_t value) {
  H5::Attribute attr = obj.createAttribute(name, H5::PredType::STD_I32LE, H5::DataSpace(H5S_SCALAR));
  attr.write(H5::PredType::NATIVE_INT32, &value);
}

// Writes an HDF5 file through the project's atomic writer (common/file_io.h): `fill` builds the
// file in memory (HDF5's core driver, no backing store), then the file image is written by
// AtomicFile. HDF5 never touches the disk: a full disk or an I/O error is reported by AtomicFile,
// naming the file and the system's reason, and leaves nothing at `path`. (Written by HDF5 itself,
// a failed flush left a file libhdf5 1.10 could not close, and it crashed at exit closing it
// again: found by train/cli/full_disk_test.) Costs the file's size in memory, once more while the
// image is copied out. H5::Exception from `fill` propagates.
inline void write_h5_atomically(const std::filesystem::path& path, const std::function<void(H5::H5File&)>& fill) {
  std::vector<char> image;
  {
    H5::FileAccPropList access;
    // Grow by 1 MB, no file on disk. (The core driver zeroes each increment: 64 MB made every
    // small checkpoint cost ~4 s of page faults on a virtual machine.)
    access.setCore(1 << 20, false);
    H5::H5File file(path.filename().string(), H5F_ACC_TRUNC, H5::FileCreatPropList::DEFAULT, access);
    fill(file);
    file.flush(H5F_SCOPE_GLOBAL);
    const ssize_t size = H5Fget_file_image(file.getId(), nullptr, 0);
    if (size < 0) throw H5::FileIException("H5Fget_file_image", "cannot get the size of the file image");
    image.resize(static_cast<size_t>(size));
    if (H5Fget_file_image(file.getId(), image.data(), image.size()) != size) {
      throw H5::FileIException("H5Fget_file_image", "cannot copy the file image");
    }
    file.close();
  }
  write_file_atomically(path, image.data(), image.size());
}

// Reading with validation: every helper throws lmb::Error "<file>: <field>: <reason>".
class Reader {
 public:
  Reader(const std::filesystem::path& path, H5::H5File& file) : path_(path.string()), file_(file) {}

  std::string where(const std::string& field) const { return path_ + ": " + field; }

  std::string string_attribute(const char* name) {
    LMB_CHECK(file_.attrExists(name), where(std::string("attribute '") + name + "'") << ": missing");
    H5::Attribute attr = file_.openAttribute(name);
    const std::string at = where(std::string("attribute '") + name + "'");
    LMB_CHECK(attr.getTypeClass() == H5T_STRING, at << ": not a string");
    LMB_CHECK(attr.getSpace().getSimpleExtentNpoints() == 1, at << ": not a scalar");
    const H5::StrType type = attr.getStrType();
    std::string value;
    if (!type.isVariableStr()) {
      attr.read(type, value);
      return value;
    }
    // Variable length: read the pointer ourselves. H5::Attribute::read(type, std::string&) calls
    // strlen on whatever libhdf5 returns, a null pointer for a damaged heap entry (found by
    // test/fuzz/fuzz_map_h5).
    char* text = nullptr;
    attr.read(type, &text);
    LMB_CHECK(text != nullptr, at << ": unreadable (damaged file)");
    value = text;
    H5free_memory(text);
    return value;
  }

  int64_t int_attribute(const char* name) {
    LMB_CHECK(file_.attrExists(name), where(std::string("attribute '") + name + "'") << ": missing");
    H5::Attribute attr = file_.openAttribute(name);
    LMB_CHECK(attr.getTypeClass() == H5T_INTEGER && attr.getSpace().getSimpleExtentNpoints() == 1,
              where(std::string("attribute '") + name + "'") << ": not an integer scalar");
    int64_t value = 0;
    attr.read(H5::PredType::NATIVE_INT64, &value);
    return value;
  }

  // Reads dataset `name` ("/group/column") of the given rank; rows must equal `rows` when rows >= 0
  // and cols must equal `cols` for rank 2 (when cols >= 0). Returns the data and the row count.
  template <typename T>
  std::vector<T> column(const std::string& name, int64_t rows, int rank = 1, int64_t cols = -1,
                        int64_t* rows_out = nullptr) {
    const std::string at = where("dataset '" + name + "'");
    LMB_CHECK(file_.nameExists(name), at << ": missing");
    H5::DataSet ds = file_.openDataSet(name);
    const H5T_class_t want = std::is_floating_point_v<T> ? H5T_FLOAT : H5T_INTEGER;
    LMB_CHECK(ds.getTypeClass() == want,
              at << ": wrong element type (expected " << (want == H5T_FLOAT ? "float" : "integer") << ")");
    H5::DataSpace space = ds.getSpace();
    LMB_CHECK(space.isSimple() && space.getSimpleExtentNdims() == rank,
              at << ": expected " << rank << " dimension(s), found " << space.getSimpleExtentNdims());
    hsize_t dims[2] = {0, 0};
    space.getSimpleExtentDims(dims);
    LMB_CHECK(rows < 0 || static_cast<int64_t>(dims[0]) == rows,
              at << ": has " << dims[0] << " rows, expected " << rows);
    if (rank == 2) {
      LMB_CHECK(cols < 0 || static_cast<int64_t>(dims[1]) == cols,
                at << ": has " << dims[1] << " columns, expected " << cols);
    }
    // The bytes stored in the file bound the shape (datasets are contiguous and uncompressed): a
    // damaged shape must not allocate beyond the file (found by test/fuzz/fuzz_checkpoint).
    const hsize_t per_row = rank == 2 ? dims[1] : 1;
    const hsize_t stored = ds.getStorageSize();
    const size_t element = ds.getDataType().getSize();
    LMB_CHECK(element > 0 && (per_row == 0 || dims[0] <= stored / element / per_row),
              at << ": shape " << dims[0] << " x " << per_row << " exceeds the " << stored << " bytes stored");
    const hsize_t count = dims[0] * per_row;
    std::vector<T> data(count);
    if (count > 0) ds.read(data.data(), mem_type<T>());
    if (rows_out) *rows_out = static_cast<int64_t>(dims[0]);
    return data;
  }

  std::vector<std::string> strings(const std::string& name, int64_t rows) {
    const std::string at = where("dataset '" + name + "'");
    LMB_CHECK(file_.nameExists(name), at << ": missing");
    H5::DataSet ds = file_.openDataSet(name);
    LMB_CHECK(ds.getTypeClass() == H5T_STRING, at << ": not a string dataset");
    H5::StrType stored = ds.getStrType();
    LMB_CHECK(stored.isVariableStr(), at << ": expected variable-length strings");
    H5::DataSpace space = ds.getSpace();
    LMB_CHECK(space.isSimple() && space.getSimpleExtentNdims() == 1, at << ": expected 1 dimension");
    hsize_t n = 0;
    space.getSimpleExtentDims(&n);
    LMB_CHECK(static_cast<int64_t>(n) == rows, at << ": has " << n << " rows, expected " << rows);
    std::vector<std::string> out(n);
    if (n == 0) return out;
    std::vector<char*> buffer(n, nullptr);
    H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
    ds.read(buffer.data(), type);
    for (hsize_t i = 0; i < n; ++i) out[i] = buffer[i] ? std::string(buffer[i]) : std::string();
    H5::DataSet::vlenReclaim(buffer.data(), type, space);
    return out;
  }

 private:
  std::string path_;
  H5::H5File& file_;
};

}  // namespace lmb::h5
