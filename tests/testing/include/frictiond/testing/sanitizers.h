#pragma once
/// @file
/// FRICTIOND_TEST_ASAN is defined when the test is built with
/// AddressSanitizer (GCC's __SANITIZE_ADDRESS__, clang's __has_feature).
/// Its malloc replaces glibc's and mallinfo2 reads zeros, so tests skip
/// checks of heap figures there.
#if defined(__SANITIZE_ADDRESS__)
#define FRICTIOND_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define FRICTIOND_TEST_ASAN 1
#endif
#endif
