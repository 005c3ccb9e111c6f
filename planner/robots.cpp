// URDF models and the built-in arms. See robots.hpp.
#include "planner/robots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include <console_bridge/console.h>
#include <tinyxml.h>
#include <urdf_parser/urdf_parser.h>

#include "core/format.hpp"
#include "planner/builtin_urdf.hpp"

namespace geotraj::planner {
namespace {

using core::Violations;

// urdfdom reports what it refuses through console_bridge, a process-wide logger. One handler,
// installed once, keeps each thread's messages in that thread's buffer (no console output,
// no interleaving between concurrent parses).
class Capture final : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level < console_bridge::CONSOLE_BRIDGE_LOG_ERROR) return;  // warnings: not ours to print
    std::string& b = buffer();
    if (!b.empty()) b += "; ";
    b += text;
  }
  static std::string& buffer() {
    thread_local std::string b;
    return b;
  }
};

void install_capture() {
  static std::once_flag once;
  std::call_once(once, [] {
    static Capture capture;
    console_bridge::useOutputHandler(&capture);
  });
}

// Where an element sits, for messages: "line 12, joint 'elbow'".
std::string where(const TiXmlElement* e) {
  std::string out = "line " + std::to_string(e->Row()) + ", " + e->Value();
  if (const char* name = e->Attribute("name")) out += std::string(" '") + name + "'";
  return out;
}

// The first child of `root` of kind `tag` named `name`, or nullptr (for a message's line).
const TiXmlElement* find_named(const TiXmlElement* root, const char* tag, const std::string& name) {
  for (const TiXmlElement* e = root->FirstChildElement(tag); e != nullptr; e = e->NextSiblingElement(tag)) {
    if (const char* n = e->Attribute("name"); n != nullptr && name == n) return e;
  }
  return nullptr;
}

// "[name]" in a urdfdom message: the joint or link it is about, to point at its line.
std::string bracketed_name(const std::string& message) {
  const auto open = message.find('[');
  const auto close = open == std::string::npos ? std::string::npos : message.find(']', open);
  return close == std::string::npos ? std::string{} : message.substr(open + 1, close - open - 1);
}

// A number attribute of the <geotraj> block: absent (nullopt), or finite, or an error.
bool read_number(const TiXmlElement* e, const char* attribute, std::optional<double>& out, Violations& v) {
  const char* text = e->Attribute(attribute);
  if (text == nullptr) return true;
  char* end = nullptr;
  const double x = std::strtod(text, &end);
  while (end != nullptr && *end == ' ') ++end;
  if (end == text || end == nullptr || *end != '\0' || !std::isfinite(x)) {
    v.push_back({"urdf", where(e) + ": " + attribute + "=\"" + text + "\" is not a finite number"});
    return false;
  }
  out = x;
  return true;
}

Eigen::Isometry3d isometry(const urdf::Pose& pose) {
  double x = 0, y = 0, z = 0, w = 1;
  pose.rotation.getQuaternion(x, y, z, w);
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::Quaterniond(w, x, y, z).normalized().toRotationMatrix();
  X.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  return X;
}

std::string listed(const std::vector<std::string>& names) {
  constexpr std::size_t kShown = 12;
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < kShown; ++i) out += (i ? ", '" : "'") + names[i] + "'";
  if (names.size() > kShown) out += ", ... (" + std::to_string(names.size()) + " in all)";
  return out;
}

std::string joint_kind(int type) {
  switch (type) {
    case urdf::Joint::FLOATING: return "floating";
    case urdf::Joint::PLANAR: return "planar";
    default: return "unknown";
  }
}

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
constexpr std::size_t kMaxUrdfBytes = 16u << 20;
constexpr std::size_t kMaxUrdfDepth = 64;
constexpr std::size_t kMaxUrdfAttributes = 64;
constexpr std::size_t kMaxUrdfValueBytes = 16384;
constexpr std::size_t kMaxUrdfMarkup = 100000;

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

// What the markup pre-checks refuse: where (an offset) and what, and whether the document is
// not XML at all (its message then says so first, as TinyXML's do) or only more than we take.
struct Refusal {
  std::size_t at;
  std::string what;
  bool malformed = true;
};

std::string hex4(unsigned value) {
  char out[16];
  std::snprintf(out, sizeof out, "U+%04X", value);
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

bool xml_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }
// TinyXML's names: a letter, '_' or any byte past ASCII, then also digits, '-', '.' and ':'.
bool name_start(char c) {
  const auto u = static_cast<unsigned char>(c);
  return (u >= 'a' && u <= 'z') || (u >= 'A' && u <= 'Z') || u == '_' || u >= 0x7F;
}
bool name_char(char c) { return name_start(c) || (c >= '0' && c <= '9') || c == '-' || c == '.' || c == ':'; }

// Text from the document for a message: whole, or its first `most` bytes cut at a character.
std::string shown(std::string_view name, std::size_t most = 64) {
  if (name.size() <= most) return std::string(name);
  std::size_t cut = most;
  while (cut > 0 && (static_cast<unsigned char>(name[cut]) & 0xC0) == 0x80) --cut;
  return std::string(name.substr(0, cut)) + "...";
}

// The markup, split as TinyXML splits it (comments, CDATA, "<!...>" and "<?...>" to their ends,
// elements with their attributes, closing tags), and checked against the bounds above. Where
// TinyXML is lenient and a lenient reading could end a tag later than TinyXML does (an XML
// declaration's values, unquoted attribute values, '<' before no name), it is refused
// instead: every tag TinyXML reads, this scan reads, so the nesting it counts is TinyXML's.
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

// The link tree, from the document itself before urdfdom builds it (urdfdom accepts a loop
// of links beside a root, and leaks it): every link the child of one joint at most, no loop.
void check_link_tree(const TiXmlElement* robot, Violations& v) {
  std::map<std::string, const TiXmlElement*> parent_joint;  // child link -> its joint
  for (const TiXmlElement* j = robot->FirstChildElement("joint"); j != nullptr; j = j->NextSiblingElement("joint")) {
    const TiXmlElement* child = j->FirstChildElement("child");
    const char* link = child ? child->Attribute("link") : nullptr;
    if (link == nullptr) continue;  // urdfdom names it
    const auto [it, fresh] = parent_joint.emplace(link, j);
    if (!fresh) {
      v.push_back({"urdf", where(j) + ": link '" + link + "' is already the child of " + where(it->second) +
                               ": a link has one parent joint"});
    }
  }
  if (!v.empty()) return;
  // Up from every link, each link visited once in all: meeting the walk's own trail is a loop.
  std::map<std::string, int> state;  // 1: on the current walk, 2: known to reach the root
  for (const auto& [link, joint] : parent_joint) {
    std::vector<std::string> trail;
    std::string at = link;
    for (;;) {
      int& st = state[at];
      if (st == 2) break;
      if (st == 1) {
        v.push_back({"urdf", where(parent_joint.at(at)) + ": the links form a loop through link '" + at +
                                 "' (a URDF is a tree: every chain of parents ends at the root)"});
        return;
      }
      st = 1;
      trail.push_back(at);
      const auto it = parent_joint.find(at);
      const TiXmlElement* parent = it == parent_joint.end() ? nullptr : it->second->FirstChildElement("parent");
      const char* up = parent ? parent->Attribute("link") : nullptr;
      if (up == nullptr) break;
      at = up;
    }
    for (const auto& l : trail) state[l] = 2;
  }
}

// The side block: per joint name, its element.
struct SideBlock {
  const TiXmlElement* element = nullptr;
  std::vector<const TiXmlElement*> joints;
};

}  // namespace

core::Expected<core::RobotModel> robot_from_urdf(std::string_view text, const UrdfOptions& options) {
  Violations v;
  std::string_view base_link = options.base_link, tip_link = options.tip_link;
  if (text.size() > kMaxUrdfBytes) {
    v.push_back({"urdf", "has " + std::to_string(text.size()) + " bytes; at most " + std::to_string(kMaxUrdfBytes)});
    return tl::unexpected(std::move(v));
  }
  // Between the stages below: the call's deadline or cancellation.
  const auto given_up = [] {
    return core::Violations{{"urdf", "was not read whole: the call's deadline passed or it was cancelled"}};
  };
  if (options.stop_at.reached()) return tl::unexpected(given_up());
  if (const std::size_t at = invalid_utf8(text); at != std::string_view::npos) {
    v.push_back({"urdf", "is not UTF-8: " + line_at(text, at) + ", byte " + std::to_string(at)});
    return tl::unexpected(std::move(v));
  }
  for (const auto& check : {forbidden_control, bad_reference, check_markup}) {
    if (options.stop_at.reached()) return tl::unexpected(given_up());
    if (const std::optional<Refusal> r = check(text)) {
      v.push_back({"urdf", (r->malformed ? "is not well-formed XML: " : "") + line_at(text, r->at) + ": " + r->what});
      return tl::unexpected(std::move(v));
    }
  }
  if (options.stop_at.reached()) return tl::unexpected(given_up());
  std::string xml(text);
  xml.append(4, '\0');  // whatever a parser reads past the end of a character is ours
  // The document first, for the line of whatever is wrong (urdfdom says what, not where).
  TiXmlDocument doc;
  doc.Parse(xml.c_str(), nullptr, TIXML_ENCODING_UTF8);
  if (doc.Error()) {
    v.push_back({"urdf", "is not well-formed XML: line " + std::to_string(doc.ErrorRow()) + ", column " +
                             std::to_string(doc.ErrorCol()) + ": " + doc.ErrorDesc()});
    return tl::unexpected(std::move(v));
  }
  const TiXmlElement* robot = doc.RootElement();
  if (robot == nullptr || std::string(robot->Value()) != "robot") {
    v.push_back({"urdf", robot == nullptr ? std::string("has no root element: a URDF document is one <robot>")
                                          : where(robot) + ": the root element must be <robot>"});
    return tl::unexpected(std::move(v));
  }

  if (options.stop_at.reached()) return tl::unexpected(given_up());
  check_link_tree(robot, v);
  if (!v.empty()) return tl::unexpected(std::move(v));
  if (options.stop_at.reached()) return tl::unexpected(given_up());

  install_capture();
  Capture::buffer().clear();
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(xml);
  if (options.stop_at.reached()) return tl::unexpected(given_up());
  if (!model) {
    std::string message = Capture::buffer();
    if (message.empty()) message = "urdfdom refused the document";
    const std::string name = bracketed_name(message);
    message = shown(message, 512);  // it may quote a whole attribute
    const TiXmlElement* at = name.empty() ? nullptr : find_named(robot, "joint", name);
    if (at == nullptr && !name.empty()) at = find_named(robot, "link", name);
    v.push_back({"urdf", (at ? where(at) + ": " : std::string()) + message});
    return tl::unexpected(std::move(v));
  }

  // The chain: base (default: the <geotraj> block's base_link, else the root) down to the tip
  // (default: the block's tip_link, else the only leaf below the base).
  const TiXmlElement* block = robot->FirstChildElement("geotraj");
  std::string block_base, block_tip;
  if (block != nullptr) {
    if (const char* b = block->Attribute("base_link"); b != nullptr && base_link.empty()) block_base = b;
    if (const char* t = block->Attribute("tip_link"); t != nullptr && tip_link.empty()) block_tip = t;
  }
  if (!block_base.empty()) base_link = block_base;
  if (!block_tip.empty()) tip_link = block_tip;
  urdf::LinkConstSharedPtr base = base_link.empty() ? model->getRoot() : model->getLink(std::string(base_link));
  std::vector<std::string> link_names;
  {
    std::vector<urdf::LinkSharedPtr> links;
    model->getLinks(links);
    for (const auto& l : links) link_names.push_back(l->name);
  }
  if (!base) {
    v.push_back({"baseLink", "names no link of the URDF ('" + quotable(base_link) + "'); its links: " +
                                 listed(link_names)});
    return tl::unexpected(std::move(v));
  }
  urdf::LinkConstSharedPtr tip;
  if (tip_link.empty()) {
    std::vector<std::string> leaves;
    std::vector<urdf::LinkConstSharedPtr> stack{base};
    while (!stack.empty()) {  // a tree (check_link_tree): each link once
      const urdf::LinkConstSharedPtr l = stack.back();
      stack.pop_back();
      if (l->child_links.empty()) {
        leaves.push_back(l->name);
        tip = l;
      }
      for (const auto& c : l->child_links) stack.push_back(c);
    }
    if (leaves.size() > 1) {
      std::sort(leaves.begin(), leaves.end());
      v.push_back({"tipLink", "is needed: the URDF branches below '" + base->name + "' into " +
                                  std::to_string(leaves.size()) + " leaf links (" + listed(leaves) +
                                  "); name the one the tool is on"});
      return tl::unexpected(std::move(v));
    }
  } else {
    tip = model->getLink(std::string(tip_link));
    if (!tip) {
      v.push_back({"tipLink", "names no link of the URDF ('" + quotable(tip_link) + "'); its links: " +
                                  listed(link_names)});
      return tl::unexpected(std::move(v));
    }
  }
  std::vector<urdf::JointConstSharedPtr> path;  // tip to base
  for (urdf::LinkConstSharedPtr l = tip; l != base;) {
    if (!l->parent_joint || path.size() > link_names.size()) {
      v.push_back({"tipLink", "'" + tip->name + "' is not below the base link '" + base->name + "'"});
      return tl::unexpected(std::move(v));
    }
    path.push_back(l->parent_joint);
    l = model->getLink(l->parent_joint->parent_link_name);
  }
  std::reverse(path.begin(), path.end());
  const auto moving = std::count_if(path.begin(), path.end(), [](const auto& j) { return j->type != urdf::Joint::FIXED; });
  if (static_cast<std::size_t>(moving) > core::kMaxJoints) {  // before any work per joint
    v.push_back({"urdf", "the chain from '" + base->name + "' to '" + tip->name + "' has " + std::to_string(moving) +
                             " moving joints; at most " + std::to_string(core::kMaxJoints) + " are supported"});
    return tl::unexpected(std::move(v));
  }
  std::map<std::string, const TiXmlElement*> joint_elements;  // for the lines of messages
  for (const TiXmlElement* e = robot->FirstChildElement("joint"); e != nullptr; e = e->NextSiblingElement("joint")) {
    if (const char* n = e->Attribute("name")) joint_elements.emplace(n, e);
  }

  core::RobotModel m;
  m.name = model->getName();
  Eigen::Isometry3d pending = Eigen::Isometry3d::Identity();  // fixed joints since the last moving one
  std::vector<const TiXmlElement*> elements;                  // each moving joint's element
  for (const auto& j : path) {
    const auto found = joint_elements.find(j->name);
    const TiXmlElement* e = found == joint_elements.end() ? nullptr : found->second;
    const std::string at = e ? where(e) : "joint '" + j->name + "'";
    const Eigen::Isometry3d origin = isometry(j->parent_to_joint_origin_transform);
    if (j->type == urdf::Joint::FIXED) {
      pending = pending * origin;
      continue;
    }
    if (j->type != urdf::Joint::REVOLUTE && j->type != urdf::Joint::CONTINUOUS &&
        j->type != urdf::Joint::PRISMATIC) {
      v.push_back({"urdf", at + ": a " + joint_kind(j->type) +
                               " joint is not a joint of a serial arm (revolute, continuous, prismatic or fixed)"});
      continue;
    }
    if (j->mimic) {
      v.push_back({"urdf", at + ": mimics joint '" + j->mimic->joint_name +
                               "'; mimic joints are not supported on the chain (give the chain without it)"});
      continue;
    }
    core::Joint joint;
    joint.name = j->name;
    joint.type = j->type == urdf::Joint::PRISMATIC    ? core::JointType::kPrismatic
                 : j->type == urdf::Joint::CONTINUOUS ? core::JointType::kContinuous
                                                      : core::JointType::kRevolute;
    joint.origin = pending * origin;
    pending = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d axis(j->axis.x, j->axis.y, j->axis.z);
    if (!axis.allFinite() || axis.norm() < 1e-9) {
      v.push_back({"urdf", at + ": <axis xyz> must be a non-zero vector"});
      continue;
    }
    joint.axis = axis.normalized();
    core::JointLimits limits;
    if (!j->limits && joint.type != core::JointType::kContinuous) {
      v.push_back({"urdf", at + ": has no <limit> (lower, upper, velocity)"});
    } else if (!j->limits || !(std::isfinite(j->limits->velocity) && j->limits->velocity > 0.0)) {
      v.push_back({"urdf", at + ": <limit velocity> must be given, finite and > 0"});
    } else {
      limits.max_velocity = j->limits->velocity;
      if (joint.type != core::JointType::kContinuous) {
        limits.min_position = j->limits->lower;
        limits.max_position = j->limits->upper;
        if (!(std::isfinite(limits.min_position) && std::isfinite(limits.max_position) &&
              limits.min_position <= limits.max_position)) {
          v.push_back({"urdf", at + ": <limit lower=\"" + core::number(limits.min_position) + "\" upper=\"" +
                                   core::number(limits.max_position) + "\"> must be finite with lower <= upper"});
        }
      }
    }
    m.joints.push_back(std::move(joint));
    m.limits.push_back(limits);
    elements.push_back(e);
  }
  m.flange = pending;
  if (m.joints.empty() && v.empty()) {
    v.push_back({"urdf", "the chain from '" + base->name + "' to '" + tip->name + "' has no moving joint"});
  }

  // The <geotraj> block: accelerations, jerks, home, description.
  SideBlock side;
  side.element = block;
  if (side.element != nullptr) {
    if (const char* d = side.element->Attribute("description")) m.description = d;
    for (const TiXmlElement* e = side.element->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
      if (std::string(e->Value()) != "joint" || e->Attribute("name") == nullptr) {
        v.push_back({"urdf", where(e) + ": the <geotraj> block holds <joint name=\"..\" max_acceleration=\"..\" "
                                        "max_jerk=\"..\" home=\"..\"/> elements only"});
        continue;
      }
      const std::string name = e->Attribute("name");
      const auto it = std::find_if(m.joints.begin(), m.joints.end(), [&](const core::Joint& j) { return j.name == name; });
      if (it == m.joints.end()) {  // a joint off the chain is someone else's; no joint at all is a typo
        const urdf::JointConstSharedPtr j = model->getJoint(name);
        if (!j || j->type == urdf::Joint::FIXED) {
          v.push_back({"urdf", where(e) + ": the URDF has no moving joint '" + name + "'"});
        }
        continue;
      }
      side.joints.push_back(e);
    }
  }
  if (m.description.empty()) m.description = "URDF robot '" + m.name + "'";
  m.home.assign(m.joints.size(), 0.0);
  for (std::size_t i = 0; i < m.joints.size(); ++i) {
    const std::string& name = m.joints[i].name;
    const TiXmlElement* entry = nullptr;
    for (const TiXmlElement* e : side.joints) {
      if (name == e->Attribute("name")) entry = e;
    }
    std::optional<double> acceleration, jerk, home;
    if (entry != nullptr) {
      read_number(entry, "max_acceleration", acceleration, v);
      read_number(entry, "max_jerk", jerk, v);
      read_number(entry, "home", home, v);
      if (acceleration && !(*acceleration > 0.0)) v.push_back({"urdf", where(entry) + ": max_acceleration must be > 0"});
      if (jerk && !(*jerk > 0.0)) v.push_back({"urdf", where(entry) + ": max_jerk must be > 0"});
    }
    for (const NamedLimits& l : options.limits) {  // the request's (checked by its caller), over the block
      if (l.joint != name) continue;
      if (l.max_acceleration) acceleration = l.max_acceleration;
      if (l.max_jerk) jerk = l.max_jerk;
      if (l.max_velocity) m.limits[i].max_velocity = *l.max_velocity;
    }
    const std::string at = elements[i] ? where(elements[i]) : "joint '" + name + "'";
    if (!acceleration && options.require_accelerations) {
      v.push_back({"urdf", at + ": has no acceleration limit, which every motion needs and URDF cannot say: give it "
                               "in a <geotraj> block beside the links, <geotraj><joint name=\"" + name +
                               "\" max_acceleration=\"...\"/></geotraj> [rad/s^2 or m/s^2], or in the request's "
                               "robot.jointLimits (docs/kinematics.md)"});
    } else {
      m.limits[i].max_acceleration = acceleration.value_or(kUnknownAcceleration);  // unknown: kinematics only
    }
    m.limits[i].max_jerk = jerk;
    const core::JointLimits& l = m.limits[i];
    const bool continuous = m.joints[i].type == core::JointType::kContinuous;
    if (home) {
      if (!core::within_position_limits(m.joints[i].type, l, *home) || std::abs(*home) > core::kMaxModelMagnitude) {
        v.push_back({"urdf", where(entry) + ": home " + core::number(*home) + " is outside the joint's limits [" +
                                 core::number(l.min_position) + ", " + core::number(l.max_position) + "]"});
      }
      m.home[i] = *home;
    } else if (!continuous && (l.min_position > 0.0 || l.max_position < 0.0)) {
      m.home[i] = 0.5 * (l.min_position + l.max_position);  // 0 is outside the range: its middle
    }
  }
  if (!v.empty()) return tl::unexpected(std::move(v));
  if (Violations rest = core::validate_robot(m); !rest.empty()) {  // the model it makes (joints[i] counts moving joints)
    for (auto& fv : rest) fv = {"urdf", "the chain's " + fv.field + " " + fv.description};
    return tl::unexpected(std::move(rest));
  }
  return m;
}

const std::vector<core::RobotModel>& builtin_robots() {
  static const std::vector<core::RobotModel> robots = [] {
    std::vector<core::RobotModel> out = core::builtin_robots();
    for (const BuiltinUrdf& b : kBuiltinUrdfs) {
      auto m = robot_from_urdf(b.text);
      if (!m) {  // a file of this repository: the tests read every one
        for (const auto& fv : m.error()) std::fprintf(stderr, "built-in %s: %s: %s\n", b.name, fv.field.c_str(), fv.description.c_str());
        GEOTRAJ_CHECK(false && "a built-in URDF does not load");
      }
      m->name = b.name;
      out.push_back(std::move(*m));
    }
    return out;
  }();
  return robots;
}

const core::RobotModel* find_builtin_robot(std::string_view name) {
  for (const auto& m : builtin_robots()) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

std::string_view builtin_urdf(std::string_view name) {
  for (const BuiltinUrdf& b : kBuiltinUrdfs) {
    if (name == b.name) return b.text;
  }
  return {};
}

}  // namespace geotraj::planner
