// Scene text as it reaches messages: checked for UTF-8, and cut to one short
// line wherever a message quotes it, so that no diagnostic shows more of a
// file than the offending line.
#pragma once
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace ces::scene {

// The offset of the first byte that is not well-formed UTF-8 (RFC 3629: no
// overlong forms, no surrogates, nothing above U+10FFFF); nullopt if all is.
std::optional<std::size_t> invalid_utf8(std::string_view text);

// The offset of the first control character other than tab, line feed and
// carriage return (YAML allows no other; nlohmann's JSON parser takes a NUL
// for the end of the text); nullopt if there is none.
std::optional<std::size_t> control_character(std::string_view text);

// The first line of `text`, cut at `max` bytes (on a character boundary)
// with "..." appended when anything was left out.
std::string excerpt(std::string_view text, std::size_t max = 40);

// The end of the run of ASCII digits that starts at s[i] (i itself if none).
std::size_t skip_digits(std::string_view s, std::size_t i);

// `text` with control characters written as escapes (\n, \t, \x01): a
// diagnostic stays on one line whatever a key or a name holds.
std::string one_line(std::string_view text);

}  // namespace ces::scene
