#include "phasecast/core/hdf5_file.h"

#include <fmt/format.h>

#include <unistd.h>
#include <algorithm>
#include <cstring>
#include <optional>

namespace phasecast::core::h5 {
namespace {

// HDF5 prints its error stack to stderr by default; the package reader reports
// its own one-line messages instead.
void silence_hdf5() {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
}

hid_t check(hid_t id, const std::string& what) {
  if (id < 0) throw Failure(what);
  return id;
}

void check(herr_t status, const std::string& what) {
  if (status < 0) throw Failure(what);
}

hid_t native_type(Dtype d) {
  switch (d) {
    case Dtype::f32:
      return H5T_NATIVE_FLOAT;
    case Dtype::f64:
      return H5T_NATIVE_DOUBLE;
    case Dtype::u8:
      return H5T_NATIVE_UINT8;
    case Dtype::u32:
      return H5T_NATIVE_UINT32;
    case Dtype::i32:
      return H5T_NATIVE_INT32;
    default:
      throw Failure("internal: no native HDF5 type for this dtype");
  }
}

// Little-endian file types, so packages written here read identically anywhere.
hid_t file_type(Dtype d) {
  switch (d) {
    case Dtype::f32:
      return H5T_IEEE_F32LE;
    case Dtype::f64:
      return H5T_IEEE_F64LE;
    case Dtype::u8:
      return H5T_STD_U8LE;
    case Dtype::u32:
      return H5T_STD_U32LE;
    case Dtype::i32:
      return H5T_STD_I32LE;
    default:
      throw Failure("internal: no HDF5 file type for this dtype");
  }
}

Dtype classify(hid_t type) {
  const H5T_class_t cls = H5Tget_class(type);
  const size_t size = H5Tget_size(type);
  if (cls == H5T_FLOAT) return size == 4 ? Dtype::f32 : size == 8 ? Dtype::f64 : Dtype::other;
  if (cls == H5T_STRING) return Dtype::string;
  if (cls == H5T_INTEGER) {
    const bool is_signed = H5Tget_sign(type) == H5T_SGN_2;
    if (!is_signed && size == 1) return Dtype::u8;
    if (!is_signed && size == 4) return Dtype::u32;
    if (is_signed && size == 4) return Dtype::i32;
  }
  return Dtype::other;
}

Handle string_type(bool variable) {
  Handle t(check(H5Tcopy(H5T_C_S1), "cannot create string type"), H5Tclose);
  check(H5Tset_size(t.get(), variable ? H5T_VARIABLE : 1), "cannot size string type");
  check(H5Tset_cset(t.get(), H5T_CSET_UTF8), "cannot set string charset");
  return t;
}

// Object headers would otherwise carry modification times, and the same
// package written twice would differ byte for byte (content hashes name packages).
Handle untimed(hid_t property_class) {
  Handle plist(check(H5Pcreate(property_class), "cannot create property list"), H5Pclose);
  check(H5Pset_obj_track_times(plist.get(), false), "cannot disable time tracking");
  return plist;
}

// Chunked layout with the Fletcher-32 filter: a flipped bit in bulk data makes
// the read fail instead of returning wrong numbers. Chunks are whole rows,
// about 1 MiB each. Empty datasets cannot be chunked and stay contiguous.
Handle checksummed_layout(const std::vector<hsize_t>& dims, size_t element_bytes) {
  Handle dcpl = untimed(H5P_DATASET_CREATE);
  hsize_t row_bytes = element_bytes;
  for (size_t i = 0; i < dims.size(); ++i) {
    if (dims[i] == 0) return dcpl;
    if (i > 0) row_bytes *= dims[i];
  }
  if (dims.empty()) return dcpl;
  std::vector<hsize_t> chunk = dims;
  chunk[0] = std::clamp<hsize_t>((1u << 20) / row_bytes, 1, dims[0]);
  check(H5Pset_chunk(dcpl.get(), static_cast<int>(chunk.size()), chunk.data()), "cannot set chunking");
  check(H5Pset_fletcher32(dcpl.get()), "cannot set the Fletcher-32 filter");
  return dcpl;
}

}  // namespace

const char* dtype_name(Dtype d) {
  switch (d) {
    case Dtype::f32:
      return "float32";
    case Dtype::f64:
      return "float64";
    case Dtype::u8:
      return "uint8";
    case Dtype::u32:
      return "uint32";
    case Dtype::i32:
      return "int32";
    case Dtype::string:
      return "string";
    default:
      return "an unsupported dtype";
  }
}

Handle& Handle::operator=(Handle&& o) noexcept {
  if (this != &o) {
    if (id_ >= 0 && closer_) closer_(id_);
    id_ = o.id_;
    closer_ = o.closer_;
    o.id_ = H5I_INVALID_HID;
  }
  return *this;
}

Handle::~Handle() {
  if (id_ >= 0 && closer_) closer_(id_);
}

File File::create(const std::filesystem::path& path) {
  silence_hdf5();
  // Format 1.8+ object headers carry metadata checksums, so corruption of the
  // file's structure is detected on read; h5py and HDF5 >= 1.8 read them.
  Handle fapl(check(H5Pcreate(H5P_FILE_ACCESS), "cannot create file access list"), H5Pclose);
  check(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_LATEST), "cannot set format bounds");
  // The root group's header is made here, not by ensure_parent_groups: untimed too.
  Handle fcpl = untimed(H5P_FILE_CREATE);
  return File(
      Handle(check(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get()), "cannot create the file"),
             H5Fclose));
}

File File::open_write(const std::filesystem::path& path) {
  silence_hdf5();
  return File(
      Handle(check(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), "cannot open for writing"), H5Fclose));
}

void File::remove(const std::string& name) {
  check(H5Ldelete(file_.get(), name.c_str(), H5P_DEFAULT), "cannot remove " + name);
}

File File::open_read(const std::filesystem::path& path) {
  silence_hdf5();
  if (H5Fis_hdf5(path.c_str()) <= 0) throw Failure("not an HDF5 file (or truncated)");
  return File(Handle(check(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT),
                           "cannot open as HDF5 (truncated or corrupt?)"),
                     H5Fclose));
}

bool File::exists(const std::string& name) const {
  // H5Lexists must be asked about every component from the root down.
  std::string prefix;
  size_t pos = 0;
  while (pos != std::string::npos) {
    pos = name.find('/', pos + 1);
    prefix = name.substr(0, pos);
    if (H5Lexists(file_.get(), prefix.c_str(), H5P_DEFAULT) <= 0) return false;
  }
  return true;
}

Handle File::open_dataset(const std::string& name) const {
  if (!exists(name)) throw Failure("missing dataset");
  return Handle(check(H5Dopen2(file_.get(), name.c_str(), H5P_DEFAULT), "cannot open dataset"), H5Dclose);
}

namespace {

// Where a dataset's raw data live and whether a filter may have shrunk them.
void describe_storage(hid_t dataset, DatasetInfo& info) {
  Handle dcpl(check(H5Dget_create_plist(dataset), "cannot read the dataset's creation properties"), H5Pclose);
  const H5D_layout_t layout = H5Pget_layout(dcpl.get());
  if (layout < 0) throw Failure("cannot read the dataset's layout");
  info.external = layout == H5D_VIRTUAL || H5Pget_external_count(dcpl.get()) != 0;
  const int filters = H5Pget_nfilters(dcpl.get());
  if (filters < 0) throw Failure("cannot read the dataset's filters");
  for (int i = 0; i < filters; ++i) {
    unsigned flags = 0;
    size_t n_values = 0;
    const H5Z_filter_t id =
        H5Pget_filter2(dcpl.get(), static_cast<unsigned>(i), &flags, &n_values, nullptr, 0, nullptr, nullptr);
    // Shuffling and checksums keep the size; anything else may compress.
    if (id != H5Z_FILTER_SHUFFLE && id != H5Z_FILTER_FLETCHER32) info.compressed = true;
  }
  info.stored_bytes = H5Dget_storage_size(dataset);  // 0 when unknown: then nothing is trusted
}

// Bytes of the data `info` declares, or nothing when that exceeds 2^64.
std::optional<std::uint64_t> declared_bytes(const DatasetInfo& info) {
  std::uint64_t bytes = info.element_bytes;
  for (const std::uint64_t d : info.dims) {
    if (d != 0 && bytes > UINT64_MAX / d) return std::nullopt;
    bytes *= d;
  }
  return bytes;
}

std::string dataset_words(const DatasetInfo& info) {
  if (info.dims.empty()) return fmt::format("a scalar {}", dtype_name(info.dtype));
  return fmt::format("a {} {} dataset", describe_dims(info.dims), dtype_name(info.dtype));
}

}  // namespace

DatasetInfo File::info(const std::string& name) const {
  Handle ds = open_dataset(name);
  Handle space(check(H5Dget_space(ds.get()), "cannot read dataspace"), H5Sclose);
  Handle type(check(H5Dget_type(ds.get()), "cannot read datatype"), H5Tclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) throw Failure("cannot read dataspace rank");
  std::vector<hsize_t> dims(static_cast<size_t>(rank)), max_dims(static_cast<size_t>(rank));
  if (rank > 0)
    check(H5Sget_simple_extent_dims(space.get(), dims.data(), max_dims.data()), "cannot read dims");
  DatasetInfo info;
  info.dims.assign(dims.begin(), dims.end());
  info.extensible = rank > 0 && max_dims[0] == H5S_UNLIMITED;
  info.dtype = classify(type.get());
  info.element_bytes = H5Tget_size(type.get());
  describe_storage(ds.get(), info);
  return info;
}

std::uint64_t File::size_bytes() const {
  hsize_t size = 0;
  check(H5Fget_filesize(file_.get(), &size), "cannot read the file size");
  return size;
}

std::string storage_problem(const DatasetInfo& info, std::uint64_t file_bytes) {
  if (info.external) {
    return "raw data stored outside the file (external storage or a virtual dataset; expected a "
           "self-contained file)";
  }
  const std::optional<std::uint64_t> bytes = declared_bytes(info);
  if (!bytes) {
    return fmt::format("declares {}, more than 2^64 bytes (expected at most what the {}-byte file holds)",
                       dataset_words(info), file_bytes);
  }
  if (info.stored_bytes > file_bytes) {
    return fmt::format("its chunk index claims {} stored bytes (expected at most the {} bytes of the file)",
                       info.stored_bytes, file_bytes);
  }
  if (!info.compressed && *bytes > info.stored_bytes) {
    return fmt::format(
        "declares {} ({} bytes) but the file stores {} bytes of it (expected all of it in the {}-byte file)",
        dataset_words(info), *bytes, info.stored_bytes, file_bytes);
  }
  if (info.compressed && *bytes / kMaxInflation > info.stored_bytes) {
    return fmt::format("declares {} ({} bytes) from {} compressed bytes (expected at most {} times as many)",
                       dataset_words(info), *bytes, info.stored_bytes, kMaxInflation);
  }
  return "";
}

void File::read_raw(const std::string& name, Dtype dtype, void* out) const {
  Handle ds = open_dataset(name);
  check(H5Dread(ds.get(), native_type(dtype), H5S_ALL, H5S_ALL, H5P_DEFAULT, out),
        "cannot read data (truncated or corrupt file?)");
}

namespace {

// Rows [first, first + count) of dataset `ds`: the file dataspace with them
// selected and a memory dataspace of their shape.
struct RowBlock {
  Handle file_space;
  Handle memory_space;
};

RowBlock select_rows(hid_t ds, std::uint64_t first, std::uint64_t count) {
  Handle file_space(check(H5Dget_space(ds), "cannot read dataspace"), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(file_space.get());
  if (rank < 1) throw Failure("expected a dataset of rows, got a scalar");
  std::vector<hsize_t> dims(static_cast<size_t>(rank));
  check(H5Sget_simple_extent_dims(file_space.get(), dims.data(), nullptr), "cannot read dims");
  if (count > dims[0] || first > dims[0] - count)
    throw Failure(fmt::format("rows {}..{} past the end ({} rows)", first, first + count, dims[0]));
  std::vector<hsize_t> start(dims.size(), 0), size = dims;
  start[0] = first;
  size[0] = count;
  Handle memory_space(check(H5Screate_simple(rank, size.data(), nullptr), "cannot make a dataspace"),
                      H5Sclose);
  check(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start.data(), nullptr, size.data(), nullptr),
        "cannot select rows");
  return {std::move(file_space), std::move(memory_space)};
}

std::vector<hsize_t> extent(hid_t ds) {
  Handle space(check(H5Dget_space(ds), "cannot read dataspace"), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 1) throw Failure("expected a dataset of rows, got a scalar");
  std::vector<hsize_t> dims(static_cast<size_t>(rank));
  check(H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr), "cannot read dims");
  return dims;
}

}  // namespace

void File::read_rows_raw(const std::string& name, Dtype dtype, std::uint64_t first, std::uint64_t count,
                         void* out) const {
  Handle ds = open_dataset(name);
  const RowBlock block = select_rows(ds.get(), first, count);
  if (count == 0) return;
  check(H5Dread(ds.get(), native_type(dtype), block.memory_space.get(), block.file_space.get(), H5P_DEFAULT,
                out),
        "cannot read rows (truncated or corrupt file?)");
}

std::uint64_t File::rows(const std::string& name) const {
  Handle ds = open_dataset(name);
  return extent(ds.get())[0];
}

void File::create_rows_raw(const std::string& name, Dtype dtype, const std::vector<std::uint64_t>& row_dims,
                           std::uint64_t chunk_bytes) {
  ensure_parent_groups(name);
  std::vector<hsize_t> dims{0}, max_dims{H5S_UNLIMITED}, chunk{1};
  hsize_t row_bytes = H5Tget_size(file_type(dtype));
  for (const std::uint64_t d : row_dims) {
    if (d == 0) throw Failure(fmt::format("{}: rows of {} cannot be empty", name, describe_dims(row_dims)));
    dims.push_back(d);
    max_dims.push_back(d);
    chunk.push_back(d);
    row_bytes *= d;
  }
  chunk[0] = std::max<hsize_t>(1, chunk_bytes / row_bytes);
  const int rank = static_cast<int>(dims.size());
  Handle space(check(H5Screate_simple(rank, dims.data(), max_dims.data()),
                     fmt::format("cannot create dataspace for {}", name)),
               H5Sclose);
  Handle dcpl = untimed(H5P_DATASET_CREATE);
  check(H5Pset_chunk(dcpl.get(), rank, chunk.data()), "cannot set chunking");
  check(H5Pset_fletcher32(dcpl.get()), "cannot set the Fletcher-32 filter");
  Handle ds(check(H5Dcreate2(file_.get(), name.c_str(), file_type(dtype), space.get(), H5P_DEFAULT,
                             dcpl.get(), H5P_DEFAULT),
                  fmt::format("cannot create dataset {}", name)),
            H5Dclose);
}

void File::write_rows_raw(const std::string& name, Dtype dtype, std::uint64_t first, const void* data,
                          std::uint64_t count) {
  Handle ds = open_dataset(name);
  std::vector<hsize_t> dims = extent(ds.get());
  if (first > dims[0])
    throw Failure(fmt::format("{}: cannot write from row {}, past the end ({} rows)", name, first, dims[0]));
  dims[0] = first + count;
  check(H5Dset_extent(ds.get(), dims.data()),
        fmt::format("cannot resize {} to {} rows (expected an extensible dataset)", name, dims[0]));
  if (count == 0) return;
  const RowBlock block = select_rows(ds.get(), first, count);
  check(H5Dwrite(ds.get(), native_type(dtype), block.memory_space.get(), block.file_space.get(), H5P_DEFAULT,
                 data),
        fmt::format("cannot write rows {}..{} of {}", first, first + count, name));
}

void File::set_rows(const std::string& name, std::uint64_t rows) {
  Handle ds = open_dataset(name);
  std::vector<hsize_t> dims = extent(ds.get());
  dims[0] = rows;
  check(H5Dset_extent(ds.get(), dims.data()),
        fmt::format("cannot resize {} to {} rows (expected an extensible dataset)", name, rows));
}

std::vector<std::string> File::read_strings(const std::string& name) const {
  Handle ds = open_dataset(name);
  Handle type(check(H5Dget_type(ds.get()), "cannot read datatype"), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_STRING) throw Failure("expected strings");
  Handle space(check(H5Dget_space(ds.get()), "cannot read dataspace"), H5Sclose);
  const hssize_t n = H5Sget_simple_extent_npoints(space.get());
  if (n < 0) throw Failure("cannot read string count");
  std::vector<std::string> result;
  if (H5Tis_variable_str(type.get()) > 0) {
    Handle mem = string_type(true);
    std::vector<char*> raw(static_cast<size_t>(n), nullptr);
    const herr_t status = H5Dread(ds.get(), mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, raw.data());
    if (status >= 0) {
      for (char* s : raw) result.emplace_back(s ? s : "");
    }
    // Also after a failed read: the strings read before the failure are ours to free.
    H5Dvlen_reclaim(mem.get(), space.get(), H5P_DEFAULT, raw.data());
    check(status, "cannot read strings");
  } else {
    const size_t width = H5Tget_size(type.get());
    std::vector<char> raw(static_cast<size_t>(n) * width);
    check(H5Dread(ds.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, raw.data()), "cannot read strings");
    for (hssize_t i = 0; i < n; ++i) {
      const char* s = raw.data() + static_cast<size_t>(i) * width;
      result.emplace_back(s, strnlen(s, width));
    }
  }
  return result;
}

void File::ensure_parent_groups(const std::string& name) {
  size_t pos = 0;
  while ((pos = name.find('/', pos + 1)) != std::string::npos) {
    const std::string group = name.substr(0, pos);
    if (H5Lexists(file_.get(), group.c_str(), H5P_DEFAULT) > 0) continue;
    Handle gcpl = untimed(H5P_GROUP_CREATE);
    Handle g(check(H5Gcreate2(file_.get(), group.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT),
                   "cannot create group " + group),
             H5Gclose);
  }
}

void File::write_raw(const std::string& name, Dtype dtype, const void* data,
                     const std::vector<std::uint64_t>& dims) {
  ensure_parent_groups(name);
  std::vector<hsize_t> hdims(dims.begin(), dims.end());
  Handle space(check(H5Screate_simple(static_cast<int>(hdims.size()), hdims.data(), nullptr),
                     "cannot create dataspace for " + name),
               H5Sclose);
  Handle dcpl = checksummed_layout(hdims, H5Tget_size(file_type(dtype)));
  Handle ds(check(H5Dcreate2(file_.get(), name.c_str(), file_type(dtype), space.get(), H5P_DEFAULT,
                             dcpl.get(), H5P_DEFAULT),
                  "cannot create dataset " + name),
            H5Dclose);
  check(H5Dwrite(ds.get(), native_type(dtype), H5S_ALL, H5S_ALL, H5P_DEFAULT, data),
        "cannot write dataset " + name);
}

void File::write_strings(const std::string& name, const std::vector<std::string>& values) {
  ensure_parent_groups(name);
  Handle type = string_type(true);
  const hsize_t n = values.size();
  Handle space(check(H5Screate_simple(1, &n, nullptr), "cannot create dataspace"), H5Sclose);
  Handle dcpl = untimed(H5P_DATASET_CREATE);
  Handle ds(check(H5Dcreate2(file_.get(), name.c_str(), type.get(), space.get(), H5P_DEFAULT, dcpl.get(),
                             H5P_DEFAULT),
                  "cannot create dataset " + name),
            H5Dclose);
  std::vector<const char*> raw;
  for (const auto& v : values) raw.push_back(v.c_str());
  check(H5Dwrite(ds.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, raw.data()),
        "cannot write dataset " + name);
}

void File::remove_attribute(const std::string& name) {
  check(H5Adelete(file_.get(), name.c_str()), "cannot remove attribute " + name);
}

bool File::has_attribute(const std::string& name) const {
  return H5Aexists(file_.get(), name.c_str()) > 0;
}

Dtype File::attribute_dtype(const std::string& name) const {
  Handle attr(check(H5Aopen(file_.get(), name.c_str(), H5P_DEFAULT), "cannot open attribute"), H5Aclose);
  Handle type(check(H5Aget_type(attr.get()), "cannot read attribute type"), H5Tclose);
  return classify(type.get());
}

double File::read_attribute_number(const std::string& name) const {
  Handle attr(check(H5Aopen(file_.get(), name.c_str(), H5P_DEFAULT), "cannot open attribute"), H5Aclose);
  Handle space(check(H5Aget_space(attr.get()), "cannot read attribute space"), H5Sclose);
  if (H5Sget_simple_extent_npoints(space.get()) != 1) throw Failure("expected a scalar");
  double value = 0;
  check(H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &value), "cannot read attribute");
  return value;
}

std::vector<float> File::read_attribute_floats(const std::string& name) const {
  Handle attr(check(H5Aopen(file_.get(), name.c_str(), H5P_DEFAULT), "cannot open attribute"), H5Aclose);
  Handle space(check(H5Aget_space(attr.get()), "cannot read attribute space"), H5Sclose);
  const hssize_t n = H5Sget_simple_extent_npoints(space.get());
  if (n < 0) throw Failure("cannot read attribute size");
  if (static_cast<std::uint64_t>(n) > size_bytes() / sizeof(float)) {
    throw Failure(fmt::format("declares {} floats, more than the {}-byte file holds", n, size_bytes()));
  }
  std::vector<float> values(static_cast<size_t>(n));
  check(H5Aread(attr.get(), H5T_NATIVE_FLOAT, values.data()), "cannot read attribute");
  return values;
}

std::string File::read_attribute_string(const std::string& name) const {
  Handle attr(check(H5Aopen(file_.get(), name.c_str(), H5P_DEFAULT), "cannot open attribute"), H5Aclose);
  Handle type(check(H5Aget_type(attr.get()), "cannot read attribute type"), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_STRING) throw Failure("expected a string");
  // H5Aread writes every element of the attribute: the buffers below hold
  // one string, so an array of them would overrun (found by fuzzing).
  Handle space(check(H5Aget_space(attr.get()), "cannot read attribute space"), H5Sclose);
  if (const hssize_t n = H5Sget_simple_extent_npoints(space.get()); n != 1) {
    throw Failure(fmt::format("expected one string, got {}", n));
  }
  if (H5Tis_variable_str(type.get()) > 0) {
    Handle mem = string_type(true);
    char* raw = nullptr;
    check(H5Aread(attr.get(), mem.get(), &raw), "cannot read attribute");
    std::string value = raw ? raw : "";
    H5free_memory(raw);
    return value;
  }
  const size_t width = H5Tget_size(type.get());
  if (width > size_bytes()) {
    throw Failure(
        fmt::format("declares a string of {} bytes, more than the {}-byte file holds", width, size_bytes()));
  }
  std::vector<char> raw(width + 1, '\0');
  check(H5Aread(attr.get(), type.get(), raw.data()), "cannot read attribute");
  return std::string(raw.data());
}

namespace {
void write_attr(hid_t object, const std::string& name, hid_t file_t, hid_t mem_t, const void* data, hsize_t n,
                bool scalar) {
  if (H5Aexists(object, name.c_str()) > 0) H5Adelete(object, name.c_str());
  Handle space(check(scalar ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &n, nullptr),
                     "cannot create attribute space"),
               H5Sclose);
  Handle attr(check(H5Acreate2(object, name.c_str(), file_t, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                    "cannot create attribute " + name),
              H5Aclose);
  check(H5Awrite(attr.get(), mem_t, data), "cannot write attribute " + name);
}
}  // namespace

void File::write_attribute(const std::string& name, double value) {
  write_attr(file_.get(), name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value, 1, true);
}

void File::write_attribute(const std::string& name, std::int32_t value) {
  write_attr(file_.get(), name, H5T_STD_I32LE, H5T_NATIVE_INT32, &value, 1, true);
}

void File::write_attribute(const std::string& name, const std::vector<float>& values) {
  write_attr(file_.get(), name, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, values.data(), values.size(), false);
}

void File::write_attribute(const std::string& name, const std::string& value) {
  write_attribute_on("/", name, value);
}

void File::write_attribute_on(const std::string& object, const std::string& name, const std::string& value) {
  Handle obj(check(H5Oopen(file_.get(), object.c_str(), H5P_DEFAULT), "cannot open " + object), H5Oclose);
  Handle type = string_type(true);
  const char* raw = value.c_str();
  write_attr(obj.get(), name, type.get(), type.get(), &raw, 1, true);
}

void write_atomically(const std::filesystem::path& path, const std::function<void(File&)>& fill) {
  const std::filesystem::path tmp = path.string() + ".partial-" + std::to_string(::getpid());
  try {
    {
      File f = File::create(tmp);
      fill(f);
      f.flush();
    }
    std::filesystem::rename(tmp, path);
  } catch (const Failure&) {
    std::filesystem::remove(tmp);
    throw;
  } catch (const std::filesystem::filesystem_error& e) {
    std::filesystem::remove(tmp);
    throw Failure(e.code().message());
  }
}

void File::flush() {
  check(H5Fflush(file_.get(), H5F_SCOPE_GLOBAL), "cannot flush the file");
}

// ---- checked reading ------------------------------------------------------------

std::string describe_dims(const std::vector<std::uint64_t>& dims) {
  if (dims.empty()) return "a scalar";
  std::string s;
  for (size_t i = 0; i < dims.size(); ++i) s += (i ? "x" : "") + std::to_string(dims[i]);
  return s;
}

void Reader::fail(const std::string& where, const std::string& what) const {
  const std::string line = source_ + ": " + where + ": " + what;
  raise_(line);
  throw Failure(line);  // only if `raise` returned
}

std::string Reader::length_mismatch(Eigen::Index expected, Eigen::Index got) {
  return "expected " + std::to_string(expected) + " values, got " + std::to_string(got);
}

DatasetInfo Reader::require(const std::string& name, Dtype dtype, size_t ndim) const {
  const std::string expected = std::to_string(ndim) + "-D " + dtype_name(dtype);
  if (!file_.exists(name)) fail(name, "missing dataset (expected " + expected + ")");
  DatasetInfo info;
  try {
    info = file_.info(name);
  } catch (const Failure& e) {
    fail(name, e.what());
  }
  if (info.dims.size() != ndim || info.dtype != dtype) {
    fail(name, "expected a " + expected + " dataset, got " + describe_dims(info.dims) + " " +
                   dtype_name(info.dtype));
  }
  std::string problem;
  try {
    problem = storage_problem(info, file_.size_bytes());
  } catch (const Failure& e) {
    fail(name, e.what());
  }
  if (!problem.empty()) fail(name, problem);
  return info;
}

DatasetInfo Reader::require_shape(const std::string& name, Dtype dtype,
                                  const std::vector<std::uint64_t>& shape) const {
  DatasetInfo info = require(name, dtype, shape.size());
  for (size_t i = 0; i < shape.size(); ++i) {
    if (shape[i] != 0 && info.dims[i] != shape[i]) {
      std::string want;
      for (size_t k = 0; k < shape.size(); ++k)
        want += (k ? "x" : "") + (shape[k] ? std::to_string(shape[k]) : std::string("N"));
      fail(name,
           "expected a " + want + " " + dtype_name(dtype) + " dataset, got " + describe_dims(info.dims));
    }
  }
  return info;
}

std::vector<std::string> Reader::strings(const std::string& name) const {
  require(name, Dtype::string, 1);
  try {
    return file_.read_strings(name);
  } catch (const Failure& e) {
    fail(name, e.what());
  }
}

double Reader::number(const std::string& attribute) const {
  if (!file_.has_attribute(attribute)) fail("/@" + attribute, "missing root attribute (expected a number)");
  try {
    return file_.read_attribute_number(attribute);
  } catch (const Failure& e) {
    fail("/@" + attribute, e.what());
  }
}

std::vector<float> Reader::floats(const std::string& attribute) const {
  if (!file_.has_attribute(attribute)) fail("/@" + attribute, "missing root attribute (expected floats)");
  try {
    return file_.read_attribute_floats(attribute);
  } catch (const Failure& e) {
    fail("/@" + attribute, e.what());
  }
}

std::string Reader::text(const std::string& attribute) const {
  if (!file_.has_attribute(attribute)) fail("/@" + attribute, "missing root attribute (expected a string)");
  try {
    return file_.read_attribute_string(attribute);
  } catch (const Failure& e) {
    fail("/@" + attribute, e.what());
  }
}

}  // namespace phasecast::core::h5
