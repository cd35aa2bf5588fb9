#include "common/file_container.h"

#include <array>
#include <cstring>

#include "common/error.h"

namespace lmb {

namespace {

std::array<uint32_t, 256> make_crc_table() {
  std::array<uint32_t, 256> table{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[i] = c;
  }
  return table;
}

void put_le(std::vector<uint8_t>& out, uint64_t value, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<uint8_t>(value >> (8 * i)));
}

uint64_t get_le(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
  return v;
}

}  // namespace

uint32_t crc32(const uint8_t* data, size_t size, uint32_t crc) {
  static const std::array<uint32_t, 256> table = make_crc_table();
  crc = ~crc;
  for (size_t i = 0; i < size; ++i) crc = table[(crc ^ data[i]) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

std::vector<uint8_t> make_container(std::string_view magic, uint32_t version, const std::string& payload) {
  LMB_CHECK(magic.size() == 8, "container magic must be 8 bytes");
  std::vector<uint8_t> out(magic.begin(), magic.end());
  put_le(out, version, 4);
  put_le(out, payload.size(), 8);
  put_le(out, crc32(reinterpret_cast<const uint8_t*>(payload.data()), payload.size()), 4);
  out.insert(out.end(), payload.begin(), payload.end());
  return out;
}

std::string open_container(const uint8_t* data, size_t size, std::string_view magic, uint32_t version,
                           const std::string& what) {
  return open_container(data, size, magic, version, version, what, nullptr);
}

std::string open_container(const uint8_t* data, size_t size, std::string_view magic, uint32_t min_version,
                           uint32_t max_version, const std::string& what, uint32_t* version) {
  LMB_CHECK(size >= kContainerHeaderBytes,
            what << ": file too short (" << size << " bytes) for a " << magic << " header");
  LMB_CHECK(std::memcmp(data, magic.data(), 8) == 0, what << ": not a " << magic << " file (wrong magic)");
  const uint32_t file_version = static_cast<uint32_t>(get_le(data + 8, 4));
  if (min_version == max_version) {
    LMB_CHECK(file_version == min_version, what << ": format version " << file_version
                                                << " is not supported (this build reads version " << min_version
                                                << ")");
  } else {
    LMB_CHECK(file_version >= min_version && file_version <= max_version,
              what << ": format version " << file_version << " is not supported (this build reads versions "
                   << min_version << " to " << max_version << ")");
  }
  if (version != nullptr) *version = file_version;
  const uint64_t length = get_le(data + 12, 8);
  LMB_CHECK(length == size - kContainerHeaderBytes, what << ": truncated or padded: header says " << length
                                                         << " payload bytes, file has "
                                                         << size - kContainerHeaderBytes);
  const uint32_t expected_crc = static_cast<uint32_t>(get_le(data + 20, 4));
  const uint32_t actual_crc = crc32(data + kContainerHeaderBytes, length);
  LMB_CHECK(expected_crc == actual_crc, what << ": CRC mismatch (file is corrupt)");
  return std::string(reinterpret_cast<const char*>(data + kContainerHeaderBytes), length);
}

void write_container_file(const std::filesystem::path& path, std::string_view magic, uint32_t version,
                          const std::string& payload) {
  const std::vector<uint8_t> bytes = make_container(magic, version, payload);
  write_file_atomically(path, bytes.data(), bytes.size());
}

std::string read_container_file(const std::filesystem::path& path, std::string_view magic, uint32_t version) {
  return read_container_file(path, magic, version, version, nullptr);
}

std::string read_container_file(const std::filesystem::path& path, std::string_view magic, uint32_t min_version,
                                uint32_t max_version, uint32_t* version) {
  const std::string bytes = read_file(path);
  return open_container(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), magic, min_version, max_version,
                        path.string(), version);
}

}  // namespace lmb
