#pragma once
/// @file
/// SHA-256, HMAC-SHA256 and helpers over OpenSSL libcrypto, shared by API
/// tokens (stored as SHA-256 hashes) and signed LCM writes. Byte strings are
/// std::string (any bytes, not only text).

#include <cstddef>
#include <optional>
#include <string>

namespace frictiond {

/// HMAC-SHA256 of `data` under `key` (RFC 2104 / FIPS 198-1): 32 raw bytes.
/// @throws std::runtime_error when libcrypto fails.
std::string HmacSha256(const std::string& key, const std::string& data);

/// Lower-case hex of bytes ("\x01\xab" -> "01ab").
std::string ToHex(const std::string& bytes);

/// Bytes of a hex string (upper or lower case); nullopt when the length is
/// odd or a character is not a hex digit.
std::optional<std::string> FromHex(const std::string& hex);

/// Equality whose time does not depend on where the strings differ
/// (CRYPTO_memcmp); strings of different lengths are unequal.
bool ConstantTimeEqual(const std::string& a, const std::string& b);

/// `n` bytes from the OpenSSL CSPRNG. @throws std::runtime_error on failure.
std::string RandomBytes(std::size_t n);

/// SHA-256 of `data` (FIPS 180-4): 32 raw bytes.
std::string Sha256(const std::string& data);
/// SHA-256 of `data` as 64 lower-case hex digits.
std::string Sha256Hex(const std::string& data);
/// `n` random bytes (RandomBytes) as lower-case hex (2n digits).
std::string RandomHex(std::size_t n);

}  // namespace frictiond
