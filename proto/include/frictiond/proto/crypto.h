#pragma once
/// @file
/// Hashing primitives shared by API tokens (server) and signed LCM writes:
/// SHA-256 and HMAC-SHA256 (OpenSSL libcrypto), lowercase hex output, and
/// random secrets. No I/O except RandomHex (reads the kernel's CSPRNG).

#include <cstddef>
#include <string>

namespace frictiond {

/// Lowercase hex of bytes.
std::string ToHex(const std::string& bytes);
/// SHA-256 of `data` as 32 raw bytes.
std::string Sha256(const std::string& data);
/// SHA-256 of `data` as 64 lowercase hex digits.
std::string Sha256Hex(const std::string& data);
/// HMAC-SHA256 of `message` under `key` as 32 raw bytes.
std::string HmacSha256(const std::string& key, const std::string& message);
/// HMAC-SHA256 as 64 lowercase hex digits.
std::string HmacSha256Hex(const std::string& key, const std::string& message);
/// True when a and b are equal, in time independent of where they differ.
bool ConstantTimeEquals(const std::string& a, const std::string& b);
/// `bytes` random bytes from /dev/urandom as lowercase hex.
/// @throws std::runtime_error when the kernel's generator cannot be read.
std::string RandomHex(std::size_t bytes);

}  // namespace frictiond
