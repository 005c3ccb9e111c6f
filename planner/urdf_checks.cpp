// The checks a URDF document's text passes before TinyXML and urdfdom see it (the bounds and
// why: urdf_detail.hpp): UTF-8, control characters, character references, and the markup as
// TinyXML splits it. See robots.hpp.
#include "planner/urdf_detail.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace geotraj::planner::urdf_detail {
namespace {

std::string hex4(unsigned value) {
  char out[16];
  std::snprintf(out, sizeof out, "U+%04X", value);
  return out;
}

bool xml_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }
// TinyXML's names: a letter, '_' or any byte past ASCII, then also digits, '-', '.' and ':'.
bool name_start(char c) {
  const auto u = static_cast<unsigned char>(c);
  return (u >= 'a' && u <= 'z') || (u >= 'A' && u <= 'Z') || u == '_' || u >= 0x7F;
}
bool name_char(char c) { return name_start(c) || (c >= '0' && c <= '9') || c == '-' || c == '.' || c == ':'; }

}  // namespace

std::string line_at(std::string_view text, std::size_t offset) {
  return "line " + std::to_string(1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(offset), '\n'));
}

// The offset of the first byte that is not part of well-formed UTF-8 (no overlong form, no
// UTF-16 surrogate, nothing past U+10FFFF), or npos.
std::size_t invalid_utf8(std::string_view text) {
  std::size_t i = 0;
  while (i < text.size()) {
    const auto c = static_cast<unsigned char>(text[i]);
    std::size_t extra = 0;
    unsigned char low = 0x80, high = 0xBF;  // the range of the second byte
    if (c < 0x80) {
      extra = 0;
    } else if (c >= 0xC2 && c <= 0xDF) {
      extra = 1;
    } else if (c >= 0xE0 && c <= 0xEF) {
      extra = 2;
      if (c == 0xE0) low = 0xA0;   // overlong below
      if (c == 0xED) high = 0x9F;  // surrogates above
    } else if (c >= 0xF0 && c <= 0xF4) {
      extra = 3;
      if (c == 0xF0) low = 0x90;   // overlong below
      if (c == 0xF4) high = 0x8F;  // past U+10FFFF above
    } else {
      return i;
    }
    if (i + extra >= text.size() && extra > 0) return i;
    for (std::size_t k = 1; k <= extra; ++k) {
      const auto b = static_cast<unsigned char>(text[i + k]);
      if (b < (k == 1 ? low : 0x80) || b > (k == 1 ? high : 0xBF)) return i;
    }
    i += extra + 1;
  }
  return std::string_view::npos;
}

// A link name the caller gave, as an error message may quote it: as it is when it is
// well-formed UTF-8, else with every byte past ASCII written \xNN (a message goes back to
// the client in a protobuf string), and at most 256 bytes of it.
std::string quotable(std::string_view name) {
  name = name.substr(0, 256);
  if (invalid_utf8(name) == std::string_view::npos) return std::string(name);
  std::string out;
  for (const char ch : name) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x80) {
      out.push_back(ch);
    } else {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out.push_back(kHex[c >> 4]);
      out.push_back(kHex[c & 0xF]);
    }
  }
  return out;
}

// The first control character XML forbids (all of C0 but tab, line feed and carriage return;
// TinyXML would also stop at a NUL and drop the rest unread).
std::optional<Refusal> forbidden_control(std::string_view text) {
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 && c != '\t' && c != '\n' && c != '\r') {
      return Refusal{i, "the control character " + hex4(c) + " (byte " + std::to_string(i) + ") is not allowed in XML"};
    }
  }
  return std::nullopt;
}

// The first character reference (&#digits; or &#xhex;) that is malformed or names anything but
// ASCII text, a tab or a line break. The message quotes the reference (ASCII: '&#', 'x' and
// digits; a long run of digits cut), never what it would decode to.
std::optional<Refusal> bad_reference(std::string_view text) {
  constexpr std::size_t kShownDigits = 8;
  for (std::size_t at = text.find("&#"); at != std::string_view::npos; at = text.find("&#", at + 2)) {
    std::size_t k = at + 2;
    const bool hex = k < text.size() && text[k] == 'x';
    if (hex) ++k;
    const std::size_t digits = k;
    std::uint32_t value = 0;
    bool huge = false;  // past U+10FFFF: no longer summed
    for (; k < text.size(); ++k) {
      const char c = text[k];
      int d = -1;
      if (c >= '0' && c <= '9') d = c - '0';
      if (hex && c >= 'a' && c <= 'f') d = c - 'a' + 10;
      if (hex && c >= 'A' && c <= 'F') d = c - 'A' + 10;
      if (d < 0) break;
      if (!huge) value = value * (hex ? 16u : 10u) + static_cast<std::uint32_t>(d);
      huge = huge || value > 0x10FFFF;
    }
    const bool closed = k < text.size() && text[k] == ';';
    std::string ref(text.substr(at, std::min(k, digits + kShownDigits) - at));
    if (k > digits + kShownDigits) ref += "...";
    if (closed) ref += ';';
    ref = "the character reference \"" + ref + "\"";
    if (k == digits || !closed) {
      return Refusal{at, ref + " is malformed: a reference is &#digits; or &#xhexdigits; (write &amp; for a '&' in text)"};
    }
    if (huge) return Refusal{at, ref + " is past U+10FFFF, the last Unicode character"};
    if (value >= 0xD800 && value <= 0xDFFF) return Refusal{at, ref + " names a UTF-16 surrogate, not a character"};
    if (value < 0x20 && value != '\t' && value != '\n' && value != '\r') {
      return Refusal{at, ref + " names the control character " + hex4(value) + ", which XML does not allow"};
    }
    if (value >= 0x80) {
      return Refusal{at, ref + " names a character beyond ASCII (" + hex4(value) + "): write the character itself "
                               "(UTF-8); urdfdom would read the reference as one byte", false};
    }
  }
  return std::nullopt;
}

// Text from the document for a message: whole, or its first `most` bytes cut at a character.
std::string shown(std::string_view name, std::size_t most) {
  if (name.size() <= most) return std::string(name);
  std::size_t cut = most;
  while (cut > 0 && (static_cast<unsigned char>(name[cut]) & 0xC0) == 0x80) --cut;
  return std::string(name.substr(0, cut)) + "...";
}

// The markup, split as TinyXML splits it (comments, CDATA, "<!...>" and "<?...>" to their ends,
// elements with their attributes, closing tags), and checked against the bounds of
// urdf_detail.hpp. Where TinyXML is lenient and a lenient reading could end a tag later than
// TinyXML does (an XML declaration's values, unquoted attribute values, '<' before no name),
// it is refused instead: every tag TinyXML reads, this scan reads, so the nesting it counts
// is TinyXML's.
std::optional<Refusal> check_markup(std::string_view text) {
  const std::size_t n = text.size();
  std::size_t i = 0;
  const auto skip_space = [&] {
    while (i < n && xml_space(text[i])) ++i;
  };
  const auto read_name = [&] {
    const std::size_t start = i;
    if (i < n && name_start(text[i])) {
      for (++i; i < n && name_char(text[i]);) ++i;
    }
    return text.substr(start, i - start);
  };
  const auto past = [&](std::size_t from, std::string_view end) {
    const auto at = text.find(end, std::min(from, n));
    return at == std::string_view::npos ? n : at + end.size();
  };
  struct Open {
    std::string_view name;
    std::size_t at;
  };
  std::vector<Open> open;  // at most kMaxUrdfDepth
  std::size_t markup = 0;   // elements, attributes, comments, ...: TinyXML's objects
  const std::string too_much_markup = "more than " + std::to_string(kMaxUrdfMarkup) +
                                      " elements, attributes, comments and other markup (a URDF has a few thousand)";
  while ((i = text.find('<', i)) != std::string_view::npos) {
    const std::size_t at = i;
    const std::string_view rest = text.substr(i);
    if (!rest.starts_with("</") && ++markup > kMaxUrdfMarkup) {
      return Refusal{at, too_much_markup, false};
    }
    if (rest.starts_with("<!--")) {
      i = past(i + 4, "-->");
    } else if (rest.starts_with("<![CDATA[")) {
      i = past(i + 9, "]]>");
    } else if (rest.size() >= 5 && rest.starts_with("<?") && (rest[2] | 0x20) == 'x' && (rest[3] | 0x20) == 'm' &&
               (rest[4] | 0x20) == 'l') {
      // TinyXML's declaration: read token by token, a version, encoding or standalone value to
      // its closing quote. Only a plain one ends where its first '>' is.
      const auto refuse = [&] {
        return Refusal{at, "an XML declaration is <?xml name=\"value\" ...?>, its values without spaces, quotes, '<' "
                           "or '>' (e.g. <?xml version=\"1.0\" encoding=\"UTF-8\"?>)"};
      };
      i += 2;
      read_name();
      for (;;) {
        const std::size_t before = i;
        skip_space();
        if (text.substr(i).starts_with("?>")) break;
        if (i == before || read_name().empty()) return refuse();
        skip_space();
        if (i >= n || text[i] != '=') return refuse();
        ++i;
        skip_space();
        if (i >= n || (text[i] != '"' && text[i] != '\'')) return refuse();
        const char quote = text[i];
        for (++i; i < n && text[i] != quote; ++i) {
          if (xml_space(text[i]) || text[i] == '"' || text[i] == '\'' || text[i] == '<' || text[i] == '>') return refuse();
        }
        if (i >= n) return refuse();
        ++i;
      }
      i += 2;
    } else if (rest.starts_with("<!") || rest.starts_with("<?")) {
      i = past(i + 2, ">");  // a DOCTYPE or processing instruction: TinyXML's "unknown", to its first '>'
    } else if (rest.starts_with("</")) {
      i += 2;
      const std::string_view name = read_name();
      skip_space();
      if (name.empty() || i >= n || text[i] != '>') return Refusal{at, "a closing tag is </name>"};
      ++i;
      if (open.empty()) {
        return Refusal{at, "the closing tag </" + shown(name) + "> closes no element: none is open"};
      }
      if (name != open.back().name) {
        return Refusal{at, "the closing tag </" + shown(name) + "> does not close <" + shown(open.back().name) + "> (" +
                               line_at(text, open.back().at) + ")"};
      }
      open.pop_back();
    } else if (rest.size() >= 2 && name_start(rest[1])) {
      ++i;
      const std::string_view name = read_name();
      std::size_t attributes = 0;
      for (;;) {
        skip_space();
        if (i >= n) return std::nullopt;  // cut off: TinyXML says where
        if (text[i] == '/') {
          if (i + 1 >= n || text[i + 1] != '>') return Refusal{at, "in <" + shown(name) + ">: '/' is not followed by '>'"};
          i += 2;
          break;
        }
        if (text[i] == '>') {
          ++i;
          open.push_back({name, at});
          if (open.size() > kMaxUrdfDepth) {
            return Refusal{at, "elements nest deeper than " + std::to_string(kMaxUrdfDepth) + " levels (a URDF has 4 or 5)",
                           false};
          }
          break;
        }
        const std::size_t attribute = i;
        const std::string_view attribute_name = read_name();
        if (attribute_name.empty()) {
          return Refusal{attribute, "in <" + shown(name) + ">: expected an attribute name=\"value\", '>' or '/>'"};
        }
        skip_space();
        if (i >= n || text[i] != '=') {
          return Refusal{attribute, "in <" + shown(name) + ">: an attribute is name=\"value\" (no '=' after its name)"};
        }
        ++i;
        skip_space();
        if (i >= n || (text[i] != '"' && text[i] != '\'')) {
          return Refusal{attribute, "in <" + shown(name) + ">: an attribute is name=\"value\" (the value quoted)"};
        }
        const auto close = text.find(text[i], i + 1);
        if (close == std::string_view::npos) return std::nullopt;  // cut off: TinyXML says where
        if (close - i - 1 > kMaxUrdfValueBytes) {
          return Refusal{attribute, "in <" + shown(name) + ">: the value of " + shown(attribute_name) +
                                        " has " + std::to_string(close - i - 1) + " bytes; at most " +
                                        std::to_string(kMaxUrdfValueBytes), false};
        }
        i = close + 1;
        if (++attributes > kMaxUrdfAttributes) {
          return Refusal{at, "<" + shown(name) + "> has more than " + std::to_string(kMaxUrdfAttributes) +
                                 " attributes (a URDF element has a few)", false};
        }
        if (++markup > kMaxUrdfMarkup) return Refusal{attribute, too_much_markup, false};
      }
    } else {
      return Refusal{at, "'<' starts no tag (write &lt; for a '<' in text)"};
    }
  }
  return std::nullopt;
}

}  // namespace geotraj::planner::urdf_detail
