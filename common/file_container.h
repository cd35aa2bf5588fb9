// The versioned binary container behind every file the inference side reads (vocabulary, model):
//
//   offset 0   char[8]  magic, e.g. "LMBMODEL" or "LMBVOCAB"
//   offset 8   uint32   format version (little endian)
//   offset 12  uint64   payload length in bytes (little endian)
//   offset 20  uint32   CRC-32 (IEEE 802.3, as zlib's crc32) of the payload
//   offset 24  payload  (cereal portable binary archive)
//
// Readers check magic, version, length against the file size and the CRC before parsing a byte
// of payload, so a damaged file is an error before anything is allocated from its contents.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "common/file_io.h"

namespace lmb {

constexpr size_t kContainerHeaderBytes = 24;

uint32_t crc32(const uint8_t* data, size_t size, uint32_t crc = 0);

// Builds header + payload in memory.
std::vector<uint8_t> make_container(std::string_view magic, uint32_t version, const std::string& payload);

// Validates a container image and returns its payload. `what` names the source in errors (a path).
// Throws lmb::Error: too short, wrong magic, version not `version`, length mismatch, CRC mismatch.
std::string open_container(const uint8_t* data, size_t size, std::string_view magic, uint32_t version,
                           const std::string& what);
// The same for a reader of the versions min_version..max_version; *version (when not null)
// receives the file's.
std::string open_container(const uint8_t* data, size_t size, std::string_view magic, uint32_t min_version,
                           uint32_t max_version, const std::string& what, uint32_t* version);

// Writes atomically (common/file_io.h AtomicFile). Throws lmb::Error naming the path and the
// system's reason.
void write_container_file(const std::filesystem::path& path, std::string_view magic, uint32_t version,
                          const std::string& payload);
// Reads and validates (open_container). Throws lmb::Error naming the path: missing, a folder,
// unreadable, or any open_container error.
std::string read_container_file(const std::filesystem::path& path, std::string_view magic, uint32_t version);
std::string read_container_file(const std::filesystem::path& path, std::string_view magic, uint32_t min_version,
                                uint32_t max_version, uint32_t* version);

}  // namespace lmb
