// Bounded, valid text for what goes back to a client or into a log line: a client's 1 MB
// robot name must not become a 1 MB status message, and a cut must not split a UTF-8
// character.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace geotraj::server {

/// `text` itself when it has at most `max_bytes`; otherwise its start, cut at a UTF-8
/// character boundary and followed by "... (N more bytes)", `max_bytes` in all at most
/// (for `max_bytes` of 32 and more).
std::string truncated(std::string_view text, std::size_t max_bytes);

/// Length of the valid UTF-8 sequence that starts at s[i] (1 to 4), or 0 if none does
/// (overlong forms, surrogates and code points above U+10FFFF are not valid).
std::size_t utf8_sequence(std::string_view s, std::size_t i);

}  // namespace geotraj::server
