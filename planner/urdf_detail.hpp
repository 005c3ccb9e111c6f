// What the URDF reader (urdf.cpp) and the checks of a document's text before any parser
// sees it (urdf_checks.cpp) share. Not the planner's interface (robots.hpp).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace geotraj::planner::urdf_detail {

// What TinyXML and urdfdom cannot be given safely is refused in linear passes over the bytes
// before either parser sees them. Both parse recursively, an element per level; TinyXML
// compares each attribute with the element's earlier ones (quadratic), reads past a
// multi-byte character cut off at the end, decodes a character reference to whatever it names
// and lets a malformed one swallow the text up to the next ';', markup included. So:
//  - the size, and well-formed UTF-8 (RFC 3629) without the control characters XML forbids;
//  - every character reference well-formed and naming ASCII text, a tab or a line break
//    (urdfdom reads a reference beyond ASCII as one byte, which is not UTF-8);
//  - the markup as TinyXML splits it: elements nest at most kMaxUrdfDepth levels (a URDF has
//    4 or 5), every closing tag closes the element open (a stray one would let the nesting run
//    deeper than counted), at most kMaxUrdfAttributes attributes on an element, each value at
//    most kMaxUrdfValueBytes (urdfdom splits a vector's value into a string per space: 32
//    bytes each), and at most kMaxUrdfMarkup elements, attributes, comments and other markup
//    in all (a parser's object each, twice: a robot has a few thousand).
// What passes, TinyXML and urdfdom parse in time and memory linear in the size, at bounded
// depth (at the 16 MiB limit about 0.5 s of CPU in all; docs/kinematics.md, "Bring your own
// URDF"), and robot_from_urdf checks the caller's deadline between those stages.
inline constexpr std::size_t kMaxUrdfBytes = 16u << 20;
inline constexpr std::size_t kMaxUrdfDepth = 64;
inline constexpr std::size_t kMaxUrdfAttributes = 64;
inline constexpr std::size_t kMaxUrdfValueBytes = 16384;
inline constexpr std::size_t kMaxUrdfMarkup = 100000;

// What the markup pre-checks refuse: where (an offset) and what, and whether the document is
// not XML at all (its message then says so first, as TinyXML's do) or only more than we take.
struct Refusal {
  std::size_t at;
  std::string what;
  bool malformed = true;
};

/// "line N" of the byte at `offset` of `text`.
std::string line_at(std::string_view text, std::size_t offset);

/// The offset of the first byte of `text` that is not well-formed UTF-8, or npos.
std::size_t invalid_utf8(std::string_view text);

/// A name the caller gave, as an error message may quote it.
std::string quotable(std::string_view name);

/// Text from the document for a message, at most `most` bytes of it.
std::string shown(std::string_view name, std::size_t most = 64);

/// The pre-checks, in the order robot_from_urdf runs them: the first refusal of each, or nullopt.
std::optional<Refusal> forbidden_control(std::string_view text);
std::optional<Refusal> bad_reference(std::string_view text);
std::optional<Refusal> check_markup(std::string_view text);

}  // namespace geotraj::planner::urdf_detail
