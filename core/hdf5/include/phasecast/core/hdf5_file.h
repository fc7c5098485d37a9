#pragma once
// A small RAII layer over the HDF5 C API, shared by every file format. It turns
// every HDF5 failure into an exception (never an HDF5 error-stack dump) and
// checks dtypes exactly, because the package format promises exact dtypes.

#include "phasecast/core/eigen_types.h"

#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::core::h5 {

// Raised by this layer; the package code rethrows it as PackageError with the file name.
class Failure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Dtype { f32, f64, u8, u32, i32, string, other };
const char* dtype_name(Dtype d);

template <class T>
constexpr Dtype dtype_of();
template <>
constexpr Dtype dtype_of<float>() {
  return Dtype::f32;
}
template <>
constexpr Dtype dtype_of<double>() {
  return Dtype::f64;
}
template <>
constexpr Dtype dtype_of<std::uint8_t>() {
  return Dtype::u8;
}
template <>
constexpr Dtype dtype_of<std::uint32_t>() {
  return Dtype::u32;
}
template <>
constexpr Dtype dtype_of<std::int32_t>() {
  return Dtype::i32;
}

// Owns one hid_t and closes it with the matching H5*close.
class Handle {
 public:
  using Closer = herr_t (*)(hid_t);
  Handle() = default;
  Handle(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  Handle(Handle&& o) noexcept : id_(o.id_), closer_(o.closer_) { o.id_ = H5I_INVALID_HID; }
  Handle& operator=(Handle&& o) noexcept;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle();
  hid_t get() const { return id_; }

 private:
  hid_t id_ = H5I_INVALID_HID;
  Closer closer_ = nullptr;
};

struct DatasetInfo {
  std::vector<std::uint64_t> dims;
  Dtype dtype = Dtype::other;
  std::uint64_t element_bytes = 0;  // of one element in memory (a pointer for variable-length strings)
  std::uint64_t stored_bytes = 0;   // what the file holds for it (chunks written, contiguous extent)
  bool compressed = false;          // a filter that may shrink the data (deflate, szip, ...)
  bool external = false;            // raw data in another file: external storage or a virtual dataset
  bool extensible = false;          // the first dimension may grow without limit (create_rows)
};

// Why the file cannot hold the data `info` declares, or "" if it can: the
// bound every checked read applies before it allocates anything (issue 18:
// a header declaring 9.5 GB in a small file ended in std::bad_alloc).
// Uncompressed data must all be stored; compressed data may expand at most
// kMaxInflation times, deflate's limit; nothing may claim more than the file.
inline constexpr std::uint64_t kMaxInflation = 1032;
std::string storage_problem(const DatasetInfo& info, std::uint64_t file_bytes);

// Default chunk size of extensible datasets: small, because writing into a
// chunk rewrites all of it (it is checksummed whole); at least one row.
inline constexpr std::uint64_t kRowChunkBytes = std::uint64_t{8} << 10;

class File {
 public:
  static File create(const std::filesystem::path& path);
  static File open_read(const std::filesystem::path& path);
  static File open_write(const std::filesystem::path& path);  // existing file, read-write

  void remove(const std::string& name);
  void remove_attribute(const std::string& name);
  bool exists(const std::string& name) const;
  DatasetInfo info(const std::string& name) const;
  std::uint64_t size_bytes() const;  // of the file on disk

  // Reads the whole dataset into `out` (sized by the caller from info()).
  template <class T>
  void read(const std::string& name, T* out) const {
    read_raw(name, dtype_of<T>(), out);
  }
  // Reads rows [first, first + count) of a dataset (a block of frames; the
  // elements of a 1-D one), so large datasets can be streamed without holding
  // them in memory.
  template <class T>
  void read_rows(const std::string& name, std::uint64_t first, std::uint64_t count, T* out) const {
    read_rows_raw(name, dtype_of<T>(), first, count, out);
  }
  std::vector<std::string> read_strings(const std::string& name) const;

  template <class T>
  void write(const std::string& name, const T* data, const std::vector<std::uint64_t>& dims) {
    write_raw(name, dtype_of<T>(), data, dims);
  }
  template <class T>
  void write(const std::string& name, const RowMatrix<T>& m) {
    write(name, m.data(), {static_cast<std::uint64_t>(m.rows()), static_cast<std::uint64_t>(m.cols())});
  }
  template <class T>
  void write(const std::string& name, const std::vector<T>& v) {
    write(name, v.data(), {static_cast<std::uint64_t>(v.size())});
  }
  template <class T>
  void write(const std::string& name, const Eigen::Matrix<T, Eigen::Dynamic, 1>& v) {
    write(name, v.data(), {static_cast<std::uint64_t>(v.size())});
  }
  void write_strings(const std::string& name, const std::vector<std::string>& values);

  // Extensible datasets, for stores that grow by appending: no rows at first,
  // unlimited along the first dimension; `row_dims` are the dims of one row
  // ({} for a 1-D dataset). Chunked by about `chunk_bytes` of whole rows and
  // checksummed like write()'s datasets.
  template <class T>
  void create_rows(const std::string& name, const std::vector<std::uint64_t>& row_dims,
                   std::uint64_t chunk_bytes = kRowChunkBytes) {
    create_rows_raw(name, dtype_of<T>(), row_dims, chunk_bytes);
  }
  // Writes rows [first, first + count) of an extensible dataset and makes
  // them its last: rows before `first` are left as they are (never
  // rewritten), rows after the block are dropped.
  template <class T>
  void write_rows(const std::string& name, std::uint64_t first, const T* data, std::uint64_t count) {
    write_rows_raw(name, dtype_of<T>(), first, data, count);
  }
  // Writes `count` rows after the dataset's last.
  template <class T>
  void append_rows(const std::string& name, const T* data, std::uint64_t count) {
    write_rows(name, rows(name), data, count);
  }
  // The length of a dataset's first dimension (Failure for a scalar).
  std::uint64_t rows(const std::string& name) const;
  // Sets an extensible dataset's row count; shrinking drops the rows past `rows`.
  void set_rows(const std::string& name, std::uint64_t rows);

  bool has_attribute(const std::string& name) const;
  Dtype attribute_dtype(const std::string& name) const;
  double read_attribute_number(const std::string& name) const;
  std::string read_attribute_string(const std::string& name) const;
  std::vector<float> read_attribute_floats(const std::string& name) const;
  void write_attribute(const std::string& name, double value);
  void write_attribute(const std::string& name, std::int32_t value);
  void write_attribute(const std::string& name, const std::string& value);
  void write_attribute(const std::string& name, const std::vector<float>& values);
  // Attribute on a dataset or group rather than the root.
  void write_attribute_on(const std::string& object, const std::string& name, const std::string& value);

  void flush();

 private:
  explicit File(Handle file) : file_(std::move(file)) {}
  void read_raw(const std::string& name, Dtype dtype, void* out) const;
  void read_rows_raw(const std::string& name, Dtype dtype, std::uint64_t first, std::uint64_t count,
                     void* out) const;
  void write_raw(const std::string& name, Dtype dtype, const void* data,
                 const std::vector<std::uint64_t>& dims);
  void create_rows_raw(const std::string& name, Dtype dtype, const std::vector<std::uint64_t>& row_dims,
                       std::uint64_t chunk_bytes);
  void write_rows_raw(const std::string& name, Dtype dtype, std::uint64_t first, const void* data,
                      std::uint64_t count);
  Handle open_dataset(const std::string& name) const;
  void ensure_parent_groups(const std::string& name);
  Handle file_;
};

// "3x4", "a scalar": dataset shapes in error messages.
std::string describe_dims(const std::vector<std::uint64_t>& dims);

// Checked reading for one file format: every dataset and attribute must be
// present with the rank and exact dtype the format promises. Each failure,
// this layer's or HDF5's, becomes one line "<source>: <where>: <what>" handed
// to `raise`, which throws the format's own error type (see checked_reader).
class Reader {
 public:
  using Raise = std::function<void(const std::string& line)>;
  Reader(const File& file, std::string source, Raise raise)
      : file_(file), source_(std::move(source)), raise_(std::move(raise)) {}

  [[noreturn]] void fail(const std::string& where, const std::string& what) const;
  // The dataset's info, failing unless it exists with this rank and dtype and
  // the file holds all the data it declares (storage_problem()).
  DatasetInfo require(const std::string& name, Dtype dtype, size_t ndim) const;
  // Like require(); each nonzero entry of `shape` must also match exactly.
  DatasetInfo require_shape(const std::string& name, Dtype dtype,
                            const std::vector<std::uint64_t>& shape) const;

  template <class T>
  RowMatrix<T> matrix(const std::string& name) const {
    const auto dims = require(name, dtype_of<T>(), 2).dims;
    RowMatrix<T> m(static_cast<Eigen::Index>(dims[0]), static_cast<Eigen::Index>(dims[1]));
    read_into(name, m.data(), m.size());
    return m;
  }
  template <class T>
  std::vector<T> vector(const std::string& name) const {
    std::vector<T> v(require(name, dtype_of<T>(), 1).dims[0]);
    read_into(name, v.data(), static_cast<Eigen::Index>(v.size()));
    return v;
  }
  // A 1-D dataset as an Eigen column; `expected` >= 0 also checks its length.
  template <class T>
  Eigen::Matrix<T, Eigen::Dynamic, 1> column(const std::string& name, Eigen::Index expected = -1) const {
    const auto n = static_cast<Eigen::Index>(require(name, dtype_of<T>(), 1).dims[0]);
    if (expected >= 0 && n != expected) fail(name, length_mismatch(expected, n));
    Eigen::Matrix<T, Eigen::Dynamic, 1> v(n);
    read_into(name, v.data(), n);
    return v;
  }
  std::vector<std::string> strings(const std::string& name) const;  // a 1-D string dataset
  double number(const std::string& attribute) const;                // root attribute
  std::string text(const std::string& attribute) const;             // root attribute
  std::vector<float> floats(const std::string& attribute) const;    // root attribute
  const File& file() const { return file_; }
  const std::string& source() const { return source_; }

  // Reads `size` elements of a dataset already checked by require().
  template <class T>
  void read_into(const std::string& name, T* out, Eigen::Index size) const {
    if (size == 0) return;
    try {
      file_.read(name, out);
    } catch (const Failure& e) {
      fail(name, e.what());
    }
  }

 private:
  static std::string length_mismatch(Eigen::Index expected, Eigen::Index got);

  const File& file_;
  std::string source_;
  Raise raise_;
};

// A Reader that throws `Error` (PackageError, OrbitStoreError, ...).
template <class Error>
Reader checked_reader(const File& file, std::string source) {
  return Reader(file, std::move(source), [](const std::string& line) { throw Error(line); });
}

// Writes a new HDF5 file atomically: `fill` writes into a temporary file in
// the same folder, which is flushed and then renamed over `path`, so an
// interrupted write never leaves a partial file under the final name. Any
// failure removes the temporary file and throws Failure with the reason.
void write_atomically(const std::filesystem::path& path, const std::function<void(File&)>& fill);

}  // namespace phasecast::core::h5
