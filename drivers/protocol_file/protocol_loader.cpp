#include "drivers/protocol_file/protocol_loader.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <set>
#include <utility>

#include "drivers/printable_bytes.hpp"
#include "drivers/protocol_family.hpp"
#include "mapping/yaml_reader.hpp"

namespace fieldgate::protocol_file {

namespace {

bool is_protocol_name(std::string_view s) {
  if (s.empty() || !(s[0] >= 'a' && s[0] <= 'z')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-';
  });
}

class ProtocolParser {
 public:
  explicit ProtocolParser(YamlReader& reader) : r_(reader) {}

  ProtocolSpecPtr parse(const YAML::Node& root) {
    if (!root.IsDefined()) return nullptr;
    if (!r_.expect_map(root, "protocol file")) return nullptr;
    auto spec = std::make_shared<ProtocolSpec>();
    spec->file = r_.file();
    spec->mark = r_.mark(root);
    r_.reject_unknown_keys(
        root,
        {"protocol", "description", "manual", "framing", "address", "checksum", "errors", "numbers",
         "error_reply", "refusal_query", "unsolicited", "startup", "alignment", "commands"},
        "protocol file");
    if (auto n = r_.require(root, "protocol", "protocol file"))
      if (auto s = r_.string(*n, "protocol")) {
        spec->name = *s;
        if (!is_protocol_name(*s))
          r_.error(*n, fmt::format("protocol '{}': a name is lower case letters, digits and -, "
                                   "starting with a letter (it is a bus's 'protocol:' and a "
                                   "model's 'family:')",
                                   *s));
        else if (make_family(*s))
          r_.error(*n, fmt::format("protocol '{}' is the name of a built-in family", *s));
      }
    if (root["description"])
      spec->description = r_.string(root["description"], "description").value_or("");
    if (root["manual"]) spec->manual = r_.string(root["manual"], "manual").value_or("");
    if (root["framing"]) parse_framing(root["framing"], *spec);
    parse_address(root["address"], root, *spec);
    if (root["checksum"]) parse_checksum(root["checksum"], *spec);
    if (root["errors"]) parse_errors(root["errors"], *spec);
    // Before every reply pattern: the file's number format applies to them all.
    if (root["numbers"]) file_numbers_ = number_declaration(root["numbers"], "numbers", true);
    if (root["error_reply"]) parse_error_reply(root["error_reply"], *spec);
    if (auto c = r_.require(root, "commands", "protocol file"); c && r_.expect_map(*c, "commands"))
      for (const auto& item : *c) parse_command(item.first, item.second, *spec);
    // After the commands: these refer to them.
    for (auto& cmd : spec->commands) check_command_references(cmd, *spec);
    if (root["refusal_query"]) parse_refusal_query(root["refusal_query"], *spec);
    if (root["unsolicited"]) parse_unsolicited(root["unsolicited"], *spec);
    if (root["startup"]) parse_startup(root["startup"], *spec);
    parse_alignment(root["alignment"], root, *spec);
    return r_.diagnostics().ok() ? spec : nullptr;
  }

 private:
  // One of the named choices, or an error listing them.
  template <typename E>
  std::optional<E> choice(const YAML::Node& node, std::string_view what,
                          std::initializer_list<std::pair<std::string_view, E>> choices) {
    const auto s = r_.string(node, what).value_or("");
    std::string names;
    for (const auto& [name, value] : choices) {
      if (s == name) return value;
      names += (names.empty() ? "" : ", ") + std::string(name);
    }
    r_.error(node, fmt::format("{}: '{}' is one of {}", what, s, names));
    return std::nullopt;
  }

  // The mark of a template's character `offset` (a quoted scalar starts with its quote).
  SourceMark at(const YAML::Node& node, std::size_t offset) const {
    SourceMark m = r_.mark(node);
    if (m.line == 0) return m;
    m.column += static_cast<int>(offset) + (node.Tag() == "!" ? 1 : 0);
    return m;
  }

  std::optional<FieldPattern> pattern(const YAML::Node& node, const std::string& what) {
    const auto text = r_.string(node, what);
    if (!text) return std::nullopt;
    PatternError e;
    auto p = FieldPattern::compile(*text, e);
    if (!p) r_.diagnostics().error(at(node, e.offset), fmt::format("{}: {}", what, e.message));
    return p;
  }

  void parse_framing(const YAML::Node& node, ProtocolSpec& spec) {
    if (!r_.expect_map(node, "framing")) return;
    r_.reject_unknown_keys(
        node,
        {"send_terminator", "reply_terminator", "error_terminator", "reply_length", "echo",
         "reply_prefix", "max_reply", "command_separator"},
        "framing");
    if (node["send_terminator"])
      spec.send_terminator = r_.string(node["send_terminator"], "send_terminator").value_or("");
    if (node["reply_terminator"])
      spec.reply_terminator = r_.string(node["reply_terminator"], "reply_terminator").value_or("");
    if (node["error_terminator"])
      spec.error_terminator = r_.string(node["error_terminator"], "error_terminator").value_or("");
    if (node["reply_length"]) {
      spec.reply_length = static_cast<std::size_t>(
          r_.integer(node["reply_length"], "reply_length", 1, 1024).value_or(0));
      if (!node["reply_terminator"]) spec.reply_terminator.clear();
    }
    if (spec.reply_length == 0 && spec.reply_terminator.empty())
      r_.error(node, "framing: a reply needs a reply_terminator or a fixed reply_length");
    if (node["error_terminator"]) check_error_terminator(node["error_terminator"], spec);
    if (auto e = node["echo"])
      spec.echo = choice<ProtocolSpec::Echo>(e, "echo",
                                             {{"none", ProtocolSpec::Echo::none},
                                              {"always", ProtocolSpec::Echo::always},
                                              {"optional", ProtocolSpec::Echo::optional}})
                      .value_or(spec.echo);
    if (node["reply_prefix"])
      spec.reply_prefix = r_.string(node["reply_prefix"], "reply_prefix").value_or("");
    if (node["max_reply"])
      spec.max_reply = static_cast<std::size_t>(
          r_.integer(node["max_reply"], "max_reply", 8, 65536).value_or(256));
    if (auto c = node["command_separator"]) {
      spec.command_separator = r_.string(c, "command_separator").value_or("");
      if (spec.command_separator.empty())
        r_.error(c,
                 "framing: command_separator is the text between two commands of a line, "
                 "e.g. ';'");
      else if (spec.reply_length > 0)
        r_.error(c,
                 "framing: command_separator: the commands of a line are each answered by "
                 "their prompt, the reply_terminator, which fixed-length replies have none of");
    }
  }

  // The reply splitter ends a reply at whichever terminator comes first, so each must be told
  // from the other as the bytes arrive.
  void check_error_terminator(const YAML::Node& node, const ProtocolSpec& spec) {
    const std::string& error = spec.error_terminator;
    const std::string& reply = spec.reply_terminator;
    if (error.empty() || reply.empty()) return;
    constexpr std::string_view what_to_do =
        "give the ending only a refused reply has (Parker 6K: reply_terminator '\\r\\n> ', "
        "error_terminator '\\r\\n? ')";
    const auto e = printable_bytes(error);
    const auto r = printable_bytes(reply);
    if (error == reply) {
      r_.error(node, fmt::format("framing: error_terminator '{}' is the reply_terminator, so every "
                                 "reply would read as refused: {}",
                                 e, what_to_do));
    } else if (reply.find(error) != std::string::npos) {
      r_.error(node, fmt::format("framing: error_terminator '{}' is part of the reply_terminator "
                                 "'{}', so a reply would read as refused once that much of its "
                                 "end arrived: {}",
                                 e, r, what_to_do));
    } else if (const auto at = error.find(reply);
               at != std::string::npos && at + reply.size() != error.size()) {
      r_.error(node, fmt::format("framing: error_terminator '{}' holds the reply_terminator '{}' "
                                 "before its end, so a refusal would be cut there and read as a "
                                 "reply: {}",
                                 e, r, what_to_do));
    }
  }

  void parse_address(const YAML::Node& node, const YAML::Node& root, ProtocolSpec& spec) {
    PatternError e;
    spec.address_format = *FieldPattern::compile("{addr}", e);
    if (!node) {
      r_.error(root,
               "protocol file: 'address' is missing (its range, e.g. address: {range: [1, "
               "31]})");
      return;
    }
    if (!r_.expect_map(node, "address")) return;
    r_.reject_unknown_keys(node, {"range", "format", "formats", "broadcast"}, "address");
    if (auto range = r_.require(node, "range", "address")) {
      if (range->IsSequence() && range->size() == 2) {
        spec.address_min =
            static_cast<int>(r_.integer((*range)[0], "address range", 0, 9999).value_or(0));
        spec.address_max =
            static_cast<int>(r_.integer((*range)[1], "address range", 0, 9999).value_or(0));
        if (spec.address_max < spec.address_min)
          r_.error(*range, "address range: the first number is the lowest address");
      } else {
        r_.error(*range, "address range: [lowest, highest], e.g. [1, 31]");
      }
    }
    if (auto f = node["format"]) {
      if (auto p = pattern(f, "address format")) {
        int fields = 0;
        bool only_addr = true;
        for (const auto& piece : p->pieces())
          if (piece.field) {
            ++fields;
            only_addr = only_addr && piece.field->name == "addr";
          }
        if (fields != 1 || !only_addr)
          r_.error(f,
                   "address format: one {addr} field and any text around it, e.g. '{addr}', "
                   "'{addr:int(2)}' or '{addr} '");
        else
          spec.address_format = *p;
      }
    }
    if (auto f = node["formats"]; f && r_.expect_map(f, "address formats")) {
      for (const auto& item : f) {
        const auto n = r_.integer(item.first, "address", spec.address_min, spec.address_max);
        const auto text = r_.string(item.second, "address text");
        if (n && text) spec.address_overrides[static_cast<int>(*n)] = *text;
      }
    }
    if (node["broadcast"])
      spec.broadcast_prefix = r_.string(node["broadcast"], "address broadcast");
  }

  void parse_checksum(const YAML::Node& node, ProtocolSpec& spec) {
    if (!r_.expect_map(node, "checksum")) return;
    r_.reject_unknown_keys(node,
                           {"preset", "algorithm", "width", "poly", "init", "xor_out", "reflect",
                            "encoding", "skip", "replies"},
                           "checksum");
    ChecksumSpec c;
    if (auto p = node["preset"]) {
      const auto name = r_.string(p, "checksum preset").value_or("");
      if (auto preset = checksum_preset(name))
        c = *preset;
      else
        r_.error(p, fmt::format("checksum preset '{}' is not known (known: {})", name,
                                checksum_preset_names()));
    } else if (auto a = r_.require(node, "algorithm", "checksum (or a preset)")) {
      c.algorithm = choice<ChecksumSpec::Algorithm>(*a, "checksum algorithm",
                                                    {{"crc", ChecksumSpec::Algorithm::crc},
                                                     {"sum", ChecksumSpec::Algorithm::sum},
                                                     {"xor", ChecksumSpec::Algorithm::xor_bytes},
                                                     {"lrc", ChecksumSpec::Algorithm::lrc}})
                        .value_or(c.algorithm);
      if (c.algorithm == ChecksumSpec::Algorithm::crc && !node["poly"])
        r_.error(node, "checksum: a crc needs its poly (and init, xor_out, reflect if not 0)");
    }
    if (auto w = node["width"]) {
      c.width = static_cast<int>(r_.integer(w, "checksum width", 8, 32).value_or(8));
      if (c.width != 8 && c.width != 16 && c.width != 32)
        r_.error(w, "checksum width: 8, 16 or 32 bits");
    }
    const auto mask = c.width == 32 ? 0xFFFFFFFFLL : (int64_t{1} << c.width) - 1;
    if (node["poly"])
      c.poly = static_cast<uint64_t>(r_.integer(node["poly"], "poly", 1, mask).value_or(1));
    if (node["init"])
      c.init = static_cast<uint64_t>(r_.integer(node["init"], "init", 0, mask).value_or(0));
    if (node["xor_out"])
      c.xor_out =
          static_cast<uint64_t>(r_.integer(node["xor_out"], "xor_out", 0, mask).value_or(0));
    if (node["reflect"]) c.reflect = r_.boolean(node["reflect"], "reflect").value_or(false);
    if (auto e = node["encoding"])
      c.encoding =
          choice<ChecksumSpec::Encoding>(e, "checksum encoding",
                                         {{"hex", ChecksumSpec::Encoding::hex},
                                          {"hex_lower", ChecksumSpec::Encoding::hex_lower},
                                          {"binary_big", ChecksumSpec::Encoding::binary_big},
                                          {"binary_little", ChecksumSpec::Encoding::binary_little}})
              .value_or(c.encoding);
    if (node["skip"])
      c.skip =
          static_cast<std::size_t>(r_.integer(node["skip"], "checksum skip", 0, 16).value_or(0));
    if (node["replies"])
      spec.checksum_on_replies = r_.boolean(node["replies"], "replies").value_or(true);
    spec.checksum = c;
  }

  void parse_errors(const YAML::Node& node, ProtocolSpec& spec) {
    if (!r_.expect_map(node, "errors")) return;
    for (const auto& item : node) {
      const auto code = r_.string(item.first, "error code");
      const auto text = r_.string(item.second, "error text");
      if (code && text) spec.error_texts[*code] = *text;
    }
  }

  void parse_error_reply(const YAML::Node& node, ProtocolSpec& spec) {
    if (!r_.expect_map(node, "error_reply")) return;
    r_.reject_unknown_keys(node, {"pattern", "code", "text"}, "error_reply");
    auto p = r_.require(node, "pattern", "error_reply");
    if (!p) return;
    spec.error_reply = pattern(*p, "error_reply pattern");
    if (!spec.error_reply) return;
    declare_file_numbers(*spec.error_reply, *p);
    const auto named = [&](const char* key, std::string& out) {
      if (!node[key]) return;
      out = r_.string(node[key], std::string("error_reply ") + key).value_or("");
      for (const Field* f : spec.error_reply->named_fields())
        if (f->name == out) return;
      r_.error(node[key], fmt::format("error_reply {}: '{}' is no capture of '{}'", key, out,
                                      spec.error_reply->source()));
    };
    named("code", spec.error_reply_code);
    named("text", spec.error_reply_text);
    if (spec.error_reply_code.empty() && spec.error_reply_text.empty())
      r_.error(node, "error_reply: name its code capture (code:) or its text capture (text:)");
  }

  CaptureValue capture_value(const YAML::Node& node, const std::string& what, bool text) {
    CaptureValue v;
    v.is_text = text;
    if (text) {
      v.text = r_.string(node, what).value_or("");
    } else {
      v.number = r_.integer(node, what, INT64_MIN, INT64_MAX).value_or(0);
    }
    return v;
  }

  std::vector<int64_t> numbers(const YAML::Node& node, const std::string& what) {
    std::vector<int64_t> out;
    if (!r_.expect_sequence(node, what)) return out;
    for (const auto& n : node)
      if (auto v = r_.integer(n, what, INT64_MIN, INT64_MAX)) out.push_back(*v);
    return out;
  }

  const Field* reply_field(const CommandSpec& cmd, const YAML::Node& where, const std::string& name,
                           const std::string& what) {
    if (!cmd.reply) {
      r_.error(where, fmt::format("command {}: {} names capture '{}', but the command has no "
                                  "reply",
                                  cmd.name, what, name));
      return nullptr;
    }
    for (const Field* f : cmd.reply->named_fields())
      if (f->name == name) return f;
    std::string known;
    for (const Field* f : cmd.reply->named_fields()) known += (known.empty() ? "" : ", ") + f->name;
    r_.error(where, fmt::format("command {}: {} names capture '{}', which its reply '{}' does not "
                                "have (captures: {})",
                                cmd.name, what, name, cmd.reply->source(),
                                known.empty() ? "none" : known));
    return nullptr;
  }

  void parse_command(const YAML::Node& key, const YAML::Node& node, ProtocolSpec& spec) {
    CommandSpec cmd;
    cmd.name = r_.string(key, "command name").value_or("");
    cmd.mark = r_.mark(key);
    const std::string where = "command " + cmd.name;
    if (spec.find(cmd.name)) {
      r_.error(key, fmt::format("{}: defined twice", where));
      return;
    }
    if (!r_.expect_map(node, where)) return;
    r_.reject_unknown_keys(node,
                           {"description", "send", "reply", "replies", "prompts", "numbers",
                            "timeout", "error", "flags", "confirm"},
                           where);
    if (node["description"])
      cmd.description = r_.string(node["description"], "description").value_or("");
    bool ok = true;
    if (auto s = r_.require(node, "send", where)) {
      if (auto p = pattern(*s, where + " send")) {
        cmd.request = *p;
        for (const auto& piece : p->pieces())
          if (piece.field && (piece.field->name == "_" || piece.field->type == FieldType::text)) {
            r_.diagnostics().error(at(*s, piece.field->offset),
                                   fmt::format("{} send: {{{}}} cannot be sent (a request's fields "
                                               "are the command's parameters)",
                                               where, piece.field->name));
            ok = false;
          }
      } else {
        ok = false;
      }
    } else {
      ok = false;
    }
    const YAML::Node rep = node["reply"];
    const YAML::Node parts = node["replies"];
    if (rep && parts) {
      r_.error(parts,
               fmt::format("{}: 'reply' or 'replies' (one pattern per prompt), not both", where));
      ok = false;
    } else if (parts) {
      ok = parse_reply_parts(parts, cmd, where) && ok;
    } else if (rep) {
      if (rep.IsNull() || (rep.IsScalar() && rep.Scalar() == "none")) {
        // No reply: the confirmation below must prove the command was taken.
      } else if (auto p = pattern(rep, where + " reply")) {
        cmd.reply_parts.push_back({p->source(), 0, at(rep, 0)});
      } else {
        ok = false;
      }
    } else {
      r_.error(node, fmt::format("{}: 'reply' is missing (the reply's pattern, or none for a "
                                 "command the device does not answer)",
                                 where));
      ok = false;
    }
    if (ok) ok = frame_reply(node, cmd, spec, where);
    if (ok && cmd.reply) {
      declare_numbers(node["numbers"], cmd, where);
    } else if (ok && node["numbers"]) {
      r_.error(node["numbers"], fmt::format("{}: numbers: the command has no reply", where));
    }
    if (node["timeout"])
      cmd.timeout = r_.duration(node["timeout"], where + " timeout").value_or(cmd.timeout);
    if (ok) {
      if (auto e = node["error"]) parse_error_check(e, cmd);
      if (auto f = node["flags"]) parse_flags(f, cmd);
    }
    if (auto c = node["confirm"]) parse_confirm(c, cmd);
    if (ok && !cmd.reply && cmd.confirm.empty())
      r_.error(node, fmt::format("{}: the device answers nothing, so nothing would prove it took "
                                 "the command: give 'confirm:' (a query after it, e.g. its error "
                                 "query or a read-back)",
                                 where));
    spec.commands.push_back(std::move(cmd));
  }

  // replies: [pattern, ...]: a reply of one part per prompt, each its own pattern.
  bool parse_reply_parts(const YAML::Node& node, CommandSpec& cmd, const std::string& where) {
    if (!r_.expect_sequence(node, where + " replies")) return false;
    if (node.size() == 0 || node.size() > kMostPrompts) {
      r_.error(node,
               fmt::format("{} replies: 1 to {} patterns, one per prompt", where, kMostPrompts));
      return false;
    }
    bool ok = true;
    for (const auto& item : node) {
      if (auto p = pattern(item, where + " replies"))
        cmd.reply_parts.push_back({p->source(), 0, at(item, 0)});
      else
        ok = false;
    }
    return ok;
  }

  // How many prompts end the command's reply (`prompts:`, the parts of `replies:`, or one per
  // command of its line where the file declares the command separator), and the reply's one
  // pattern: the parts joined by the reply terminator, a bare prompt before a `reply:` for each
  // command of the line before the last.
  bool frame_reply(const YAML::Node& node, CommandSpec& cmd, const ProtocolSpec& spec,
                   const std::string& where) {
    const YAML::Node given = node["prompts"];
    const bool listed = bool(node["replies"]);
    if (given && (cmd.reply_parts.empty() || listed)) {
      r_.error(given, fmt::format("{}: prompts: {}", where,
                                  listed ? "replies gives the count, one pattern per prompt"
                                         : "the device answers nothing"));
      return false;
    }
    if (cmd.reply_parts.empty()) return true;
    std::size_t prompts = cmd.reply_parts.size();
    if (given) {
      prompts = static_cast<std::size_t>(
          r_.integer(given, where + " prompts", 1, kMostPrompts).value_or(1));
    } else if (!spec.command_separator.empty()) {
      std::size_t commands = 1;
      for (const auto& piece : cmd.request.pieces()) {
        if (piece.field) continue;
        const std::string& text = piece.literal;
        for (auto found = text.find(spec.command_separator); found != std::string::npos;
             found = text.find(spec.command_separator, found + spec.command_separator.size()))
          ++commands;
      }
      if (listed && commands != prompts) {
        r_.error(node["replies"],
                 fmt::format("{}: '{}' is a line of {} commands (separated by '{}'), each "
                             "answered by its prompt, so its reply has {} parts; replies gives "
                             "{}",
                             where, cmd.request.source(), commands,
                             printable_bytes(spec.command_separator), commands, prompts));
        return false;
      }
      prompts = std::min<std::size_t>(commands, kMostPrompts);
    }
    if (prompts > 1 && spec.reply_length > 0) {
      r_.error(given ? given : node, fmt::format("{}: a reply of {} prompts needs the "
                                                 "reply_terminator, and this file's replies "
                                                 "have a fixed length",
                                                 where, prompts));
      return false;
    }
    while (cmd.reply_parts.size() < prompts)
      cmd.reply_parts.insert(cmd.reply_parts.begin(), CommandSpec::ReplyPart{});
    std::string joined;
    const std::string terminator = as_template(spec.reply_terminator);
    // Of several parts, each with text has its own reply_prefix (one part: stripped as it comes).
    const std::string prefix = prompts > 1 ? as_template(spec.reply_prefix) : "";
    for (auto& part : cmd.reply_parts) {
      if (&part != &cmd.reply_parts.front()) joined += terminator;
      if (!part.text.empty()) joined += prefix;
      part.offset = joined.size();
      joined += part.text;
    }
    PatternError e;
    auto p = FieldPattern::compile(joined, e);
    if (!p) {
      r_.diagnostics().error(cmd.reply_mark_at(e.offset),
                             fmt::format("{} reply: {}", where, e.message));
      return false;
    }
    cmd.reply = std::move(*p);
    return true;
  }

  // Text as a template writes it: braces doubled.
  static std::string as_template(std::string_view text) {
    std::string out;
    for (const char c : text) {
      out += c;
      if (c == '{' || c == '}') out += c;
    }
    return out;
  }

  // A `numbers:` declaration (the file's, or one capture's): what it gives, and where each key
  // is written for errors.
  struct NumberDeclaration {
    std::optional<NumberFormat::Sign> sign;
    std::optional<NumberFormat::Pad> pad;
    std::optional<NumberFormat::Form> form;
    std::optional<int> places;
    int width = 0;
    YAML::Node pad_node, form_node, places_node, width_node;
  };

  std::optional<NumberDeclaration> number_declaration(const YAML::Node& node,
                                                      const std::string& what, bool file) {
    if (!r_.expect_map(node, what)) return std::nullopt;
    if (file)
      r_.reject_unknown_keys(node, {"sign", "pad"}, what);
    else
      r_.reject_unknown_keys(node, {"sign", "pad", "width", "form", "places"}, what);
    using F = NumberFormat;
    NumberDeclaration d;
    // A key in error drops the declaration: its error is enough, with none that follows from it.
    bool ok = true;
    const auto valid = [&ok](const auto& value) {
      ok = ok && value.has_value();
      return value;
    };
    if (auto n = node["sign"])
      d.sign = valid(choice<F::Sign>(n, what + " sign",
                                     {{"optional", F::Sign::optional},
                                      {"minus", F::Sign::minus},
                                      {"plus_or_minus", F::Sign::plus_or_minus},
                                      {"space_or_minus", F::Sign::space_or_minus}}));
    if (auto n = node["pad"]) {
      d.pad_node.reset(n);
      d.pad = valid(file ? choice<F::Pad>(n, what + " pad (of the fields with a width)",
                                          {{"zeros", F::Pad::zeros}, {"spaces", F::Pad::spaces}})
                         : choice<F::Pad>(n, what + " pad",
                                          {{"none", F::Pad::none},
                                           {"zeros", F::Pad::zeros},
                                           {"spaces", F::Pad::spaces}}));
    }
    if (auto n = node["width"]) {
      d.width_node.reset(n);
      d.width = static_cast<int>(valid(r_.integer(n, what + " width", 1, 32)).value_or(0));
    }
    if (auto n = node["form"]) {
      d.form_node.reset(n);
      d.form = valid(choice<F::Form>(n, what + " form",
                                     {{"integer", F::Form::integer},
                                      {"decimal", F::Form::decimal},
                                      {"exponent", F::Form::exponent}}));
    }
    if (auto n = node["places"]) {
      d.places_node.reset(n);
      if (const auto places = valid(r_.integer(n, what + " places", 0, 18)))
        d.places = static_cast<int>(*places);
    }
    if (!ok) return std::nullopt;
    return d;
  }

  // The format of one int or decimal(S) field from the file's declaration and the capture's
  // (its keys over the file's), with the field's width; nullopt where neither declares one (the
  // type's lenient reading stays) or where the capture's keys contradict the field (an error at
  // the key).
  std::optional<std::pair<NumberFormat, int>> resolve_number(const Field& f,
                                                             const NumberDeclaration* capture,
                                                             const std::string& what) {
    if (!file_numbers_ && !capture) return std::nullopt;
    const NumberDeclaration none;
    const NumberDeclaration& file = file_numbers_ ? *file_numbers_ : none;
    const NumberDeclaration& own = capture ? *capture : none;
    const std::string field = fmt::format("{{{}:{}}}", f.name, describe_type(f));
    NumberFormat n;
    n.sign = own.sign.value_or(file.sign.value_or(NumberFormat::Sign::optional));
    int width = f.width;
    if (own.width > 0) {
      if (f.width > 0 && f.width != own.width) {
        r_.error(own.width_node, fmt::format("{} width {}: {} is {} characters already", what,
                                             own.width, field, f.width));
        return std::nullopt;
      }
      width = own.width;
    }
    if (own.pad) {
      if (*own.pad == NumberFormat::Pad::none && width > 0) {
        r_.error(own.pad_node, fmt::format("{} pad: none is a number without padding, but {} is "
                                           "{} characters: pad zeros or spaces",
                                           what, field, width));
        return std::nullopt;
      }
      if (*own.pad != NumberFormat::Pad::none && width == 0) {
        r_.error(own.pad_node, fmt::format("{} pad: {} fills a fixed width, and {} has none: "
                                           "give width: N",
                                           what, to_string(*own.pad), field));
        return std::nullopt;
      }
      n.pad = *own.pad;
    } else {
      n.pad = width > 0 ? file.pad.value_or(NumberFormat::Pad::zeros) : NumberFormat::Pad::none;
    }
    n.form = own.form.value_or(f.type == FieldType::decimal ? NumberFormat::Form::decimal
                                                            : NumberFormat::Form::integer);
    if (n.form == NumberFormat::Form::decimal && f.type != FieldType::decimal) {
      r_.error(own.form_node, fmt::format("{} form: decimal: {} counts whole units; a number with "
                                          "decimals is a decimal(S) field (decimal(0) rounds it "
                                          "to a whole count)",
                                          what, field));
      return std::nullopt;
    }
    if (own.places) {
      if (n.form == NumberFormat::Form::integer) {
        r_.error(own.places_node, fmt::format("{} places: an integer has no decimals (places "
                                              "are for the decimal and exponent forms)",
                                              what));
        return std::nullopt;
      }
      n.places = *own.places;
    }
    return std::pair{n, width};
  }

  // The file's number format on every int and decimal(S) field of a pattern (error_reply,
  // unsolicited) that has no capture declarations of its own.
  void declare_file_numbers(FieldPattern& p, const YAML::Node& node) {
    if (!file_numbers_) return;
    for (std::size_t k = 0; k < p.pieces().size(); ++k) {
      const auto& piece = p.pieces()[k];
      if (!piece.field || !is_number(*piece.field)) continue;
      const auto format = resolve_number(*piece.field, nullptr, "numbers");
      PatternError e;
      if (format && !p.declare_number(k, format->first, format->second, e))
        r_.diagnostics().error(at(node, e.offset), e.message);
    }
  }

  static bool is_number(const Field& f) {
    return (f.type == FieldType::integer || f.type == FieldType::decimal) && f.name != "addr";
  }

  // A command's `numbers: {capture: {sign, pad, width, form, places}}`, and the file's, on its
  // reply's int and decimal(S) fields.
  void declare_numbers(const YAML::Node& node, CommandSpec& cmd, const std::string& where) {
    std::map<std::string, NumberDeclaration, std::less<>> own;
    if (node && r_.expect_map(node, where + " numbers")) {
      for (const auto& item : node) {
        const auto name = r_.string(item.first, where + " numbers capture").value_or("");
        const Field* f = reply_field(cmd, item.first, name, "numbers");
        if (!f) continue;
        if (!is_number(*f)) {
          r_.error(item.first, fmt::format("{} numbers: {{{}:{}}} is no int or decimal(S) field: "
                                           "a number format is for those",
                                           where, f->name, describe_type(*f)));
          continue;
        }
        if (auto d = number_declaration(item.second, where + " numbers " + name, false))
          own.emplace(name, std::move(*d));
      }
    }
    for (std::size_t k = 0; k < cmd.reply->pieces().size(); ++k) {
      const auto& piece = cmd.reply->pieces()[k];
      if (!piece.field || !is_number(*piece.field)) continue;
      const auto it = own.find(piece.field->name);
      const bool declared = it != own.end();
      const auto format =
          resolve_number(*piece.field, declared ? &it->second : nullptr,
                         where + " numbers" + (declared ? " " + it->first : std::string()));
      PatternError e;
      if (format && !cmd.reply->declare_number(k, format->first, format->second, e))
        r_.diagnostics().error(cmd.reply_mark_at(e.offset),
                               fmt::format("{} reply: {}", where, e.message));
    }
  }

  // refusal_query: COMMAND, sent after a refusal that carries no code; its error check gives the
  // code and text.
  void parse_refusal_query(const YAML::Node& node, ProtocolSpec& spec) {
    const auto name = r_.string(node, "refusal_query").value_or("");
    const CommandSpec* q = spec.find(name);
    if (!q) {
      if (!name.empty())
        r_.error(node, fmt::format("refusal_query: no command '{}' in this file", name));
      return;
    }
    if (!q->reply || !q->error || !q->parameters().empty() || !q->confirm.empty()) {
      r_.error(node, fmt::format("refusal_query: {} must be a query of the device's last error: a "
                                 "reply, an error check whose capture is the code (error: "
                                 "{{capture, ok, text}}), no parameters and no confirmation",
                                 q->name));
      return;
    }
    const bool codeless_error_reply = spec.error_reply && spec.error_reply_code.empty();
    if (spec.error_terminator.empty() && !codeless_error_reply) {
      r_.error(node,
               "refusal_query: this file has no refusal without a code to explain (a "
               "framing.error_terminator, or an error_reply without code)");
      return;
    }
    spec.refusal_query = name;
  }

  void parse_error_check(const YAML::Node& node, CommandSpec& cmd) {
    const std::string where = "command " + cmd.name + " error";
    if (!r_.expect_map(node, where)) return;
    r_.reject_unknown_keys(node, {"capture", "ok", "text"}, where);
    ErrorCheck e;
    e.mark = r_.mark(node);
    const Field* f = nullptr;
    if (auto c = r_.require(node, "capture", where)) {
      e.capture = r_.string(*c, where + " capture").value_or("");
      f = reply_field(cmd, *c, e.capture, "error");
    }
    if (auto ok = r_.require(node, "ok", where); ok && f) {
      const bool text = f->type == FieldType::character || f->type == FieldType::text;
      if (ok->IsSequence()) {
        for (const auto& v : *ok) e.ok.push_back(capture_value(v, where + " ok", text));
      } else {
        e.ok.push_back(capture_value(*ok, where + " ok", text));
      }
    }
    if (auto t = node["text"]) {
      e.text_capture = r_.string(t, where + " text").value_or("");
      reply_field(cmd, t, e.text_capture, "error text");
    }
    cmd.error = std::move(e);
  }

  void parse_flags(const YAML::Node& node, CommandSpec& cmd) {
    const std::string where = "command " + cmd.name + " flags";
    if (!r_.expect_map(node, where)) return;
    for (const auto& item : node) {
      FlagSpec flag;
      flag.name = r_.string(item.first, "flag name").value_or("");
      flag.mark = r_.mark(item.first);
      const std::string what = where + " " + flag.name;
      if (!r_.expect_map(item.second, what)) continue;
      r_.reject_unknown_keys(item.second, {"capture", "bit", "in", "not_in"}, what);
      if (auto c = r_.require(item.second, "capture", what)) {
        flag.capture = r_.string(*c, what + " capture").value_or("");
        const Field* f = reply_field(cmd, *c, flag.capture, "flag " + flag.name);
        if (f && (f->type == FieldType::text))
          r_.error(*c, fmt::format("{}: a flag tests a number, not {{{}:text}}", what, f->name));
      }
      const int given = int(bool(item.second["bit"])) + int(bool(item.second["in"])) +
                        int(bool(item.second["not_in"]));
      if (given != 1) {
        r_.error(item.second, fmt::format("{}: one of bit, in or not_in", what));
        continue;
      }
      if (item.second["bit"])
        flag.bit =
            static_cast<int>(r_.integer(item.second["bit"], what + " bit", 0, 62).value_or(0));
      if (item.second["in"]) flag.values = numbers(item.second["in"], what + " in");
      if (item.second["not_in"]) {
        flag.values = numbers(item.second["not_in"], what + " not_in");
        flag.negate = true;
      }
      cmd.flags.push_back(std::move(flag));
    }
    if (cmd.flags.size() > 16) r_.error(node, fmt::format("{}: at most 16 flags", where));
  }

  void parse_confirm(const YAML::Node& node, CommandSpec& cmd) {
    const std::string where = "command " + cmd.name + " confirm";
    const auto one = [&](const YAML::Node& item) {
      ConfirmStep step;
      step.mark = r_.mark(item);
      if (item.IsScalar()) {
        step.command = item.Scalar();
      } else if (r_.expect_map(item, where)) {
        r_.reject_unknown_keys(item, {"command", "capture", "equals", "in"}, where);
        if (auto c = r_.require(item, "command", where))
          step.command = r_.string(*c, where).value_or("");
        if (item["capture"])
          step.capture = r_.string(item["capture"], where + " capture").value_or("");
        if (item["equals"]) {
          step.equals = r_.string(item["equals"], where + " equals").value_or("");
          const auto params = cmd.parameters();
          if (std::find(params.begin(), params.end(), step.equals) == params.end())
            r_.error(item["equals"],
                     fmt::format("{}: equals '{}' is not a parameter of {}'s "
                                 "request '{}'",
                                 where, step.equals, cmd.name, cmd.request.source()));
        }
        if (item["in"]) step.in = numbers(item["in"], where + " in");
        if (!step.capture.empty() && step.equals.empty() && step.in.empty())
          r_.error(item, fmt::format("{}: a capture to check needs equals (a parameter) or in "
                                     "(values)",
                                     where));
        if (step.capture.empty() && (!step.equals.empty() || !step.in.empty()))
          r_.error(item, fmt::format("{}: equals and in need the capture they check", where));
      }
      cmd.confirm.push_back(std::move(step));
    };
    if (node.IsSequence()) {
      for (const auto& item : node) one(item);
    } else {
      one(node);
    }
  }

  // Confirmations name other commands, which may come later in the file.
  void check_command_references(CommandSpec& cmd, const ProtocolSpec& spec) {
    for (const auto& step : cmd.confirm) {
      const CommandSpec* q = spec.find(step.command);
      if (!q) {
        r_.diagnostics().error(step.mark, fmt::format("command {} confirm: no command '{}' in "
                                                      "this file",
                                                      cmd.name, step.command));
        continue;
      }
      if (!q->reply) {
        r_.diagnostics().error(step.mark, fmt::format("command {} confirm: {} has no reply, so it "
                                                      "cannot confirm anything",
                                                      cmd.name, q->name));
        continue;
      }
      if (!q->parameters().empty())
        r_.diagnostics().error(step.mark, fmt::format("command {} confirm: {} takes parameters "
                                                      "({}); a confirmation sends none",
                                                      cmd.name, q->name, q->request.source()));
      if (!q->confirm.empty())
        r_.diagnostics().error(step.mark, fmt::format("command {} confirm: {} has a confirmation "
                                                      "of its own",
                                                      cmd.name, q->name));
      if (!step.capture.empty()) {
        bool found = false;
        for (const Field* f : q->reply->named_fields()) {
          if (f->name != step.capture) continue;
          found = true;
          if (!step.in.empty() && f->type == FieldType::text)
            r_.diagnostics().error(
                step.mark, fmt::format("command {} confirm: {}'s {{{}:text}} is text, which 'in:' "
                                       "cannot compare with numbers: capture the state as a number "
                                       "(int, hex, char, bits(N)) or confirm with the command "
                                       "alone",
                                       cmd.name, q->name, f->name));
          if (!step.equals.empty())
            for (const auto& piece : cmd.request.pieces())
              if (piece.field && piece.field->name == step.equals &&
                  (piece.field->type != f->type || piece.field->scale != f->scale))
                r_.diagnostics().error(
                    step.mark,
                    fmt::format("command {} confirm: {{{}}} is sent as {} and read back as {}: "
                                "the two would never compare equal",
                                cmd.name, step.equals, describe(*piece.field), describe(*f)));
        }
        if (!found)
          r_.diagnostics().error(step.mark,
                                 fmt::format("command {} confirm: {}'s reply '{}' has "
                                             "no capture '{}'",
                                             cmd.name, q->name, q->reply->source(), step.capture));
      }
    }
  }

  static std::string describe(const Field& f) {
    if (f.type == FieldType::decimal) return fmt::format("decimal({})", f.scale);
    return std::string(to_string(f.type));
  }

  static std::string describe_type(const Field& f) {
    if (f.type != FieldType::decimal && f.width > 0)
      return fmt::format("{}({})", to_string(f.type), f.width);
    return describe(f);
  }

  void parse_unsolicited(const YAML::Node& node, ProtocolSpec& spec) {
    if (node.IsScalar()) {
      spec.unsolicited = pattern(node, "unsolicited");
      if (spec.unsolicited) declare_file_numbers(*spec.unsolicited, node);
      return;
    }
    if (!r_.expect_map(node, "unsolicited")) return;
    r_.reject_unknown_keys(node, {"pattern", "quiet_after"}, "unsolicited");
    if (auto p = r_.require(node, "pattern", "unsolicited")) {
      spec.unsolicited = pattern(*p, "unsolicited pattern");
      if (spec.unsolicited) declare_file_numbers(*spec.unsolicited, *p);
    }
    if (node["quiet_after"])
      spec.quiet_after_unsolicited = r_.duration(node["quiet_after"], "unsolicited quiet_after")
                                         .value_or(spec.quiet_after_unsolicited);
  }

  void parse_startup(const YAML::Node& node, ProtocolSpec& spec) {
    if (!r_.expect_sequence(node, "startup")) return;
    for (const auto& item : node) {
      StartupStep step;
      step.mark = r_.mark(item);
      YAML::Node name_node = item;
      if (item.IsMap() && item["discover"]) {
        r_.reject_unknown_keys(item, {"discover"}, "startup step");
        const bool second = std::any_of(spec.startup.begin(), spec.startup.end(),
                                        [](const StartupStep& s) { return s.discover; });
        if (second) {
          r_.error(item, "startup: at most one discover loop (the start-up is no program)");
          continue;
        }
        if (parse_discovery(item["discover"], spec, step)) spec.startup.push_back(std::move(step));
        continue;
      }
      if (item.IsMap()) {
        r_.reject_unknown_keys(item, {"command", "arguments", "tolerate_errors"}, "startup step");
        if (auto c = r_.require(item, "command", "startup step"))
          name_node.reset(*c);  // reset: operator= would write into item
        if (item["arguments"]) step.arguments = numbers(item["arguments"], "startup arguments");
        if (item["tolerate_errors"])
          step.tolerate_errors =
              r_.boolean(item["tolerate_errors"], "tolerate_errors").value_or(false);
      }
      step.command = r_.string(name_node, "startup command").value_or("");
      if (const CommandSpec* c = spec.find(step.command)) {
        if (c->parameters().size() != step.arguments.size())
          r_.error(item,
                   fmt::format("startup: {} takes {} argument(s) ('{}'), {} given", c->name,
                               c->parameters().size(), c->request.source(), step.arguments.size()));
        else
          for (std::size_t i = 0; i < step.arguments.size(); ++i)
            if (const auto why = argument_problem(*c, i, step.arguments[i]))
              r_.error(item["arguments"][i], fmt::format("startup: {}", *why));
      } else if (!step.command.empty()) {
        r_.error(name_node, fmt::format("startup: no command '{}' in this file", step.command));
      }
      spec.startup.push_back(std::move(step));
    }
  }

  // discover: {command, from, to, until_error, error_query, nodes}
  bool parse_discovery(const YAML::Node& node, const ProtocolSpec& spec, StartupStep& step) {
    if (!r_.expect_map(node, "discover")) return false;
    r_.reject_unknown_keys(node, {"command", "from", "to", "until_error", "error_query", "nodes"},
                           "discover");
    StartupStep::Discovery d;
    const auto name = r_.require(node, "command", "discover");
    const auto to = r_.require(node, "to", "discover");
    const auto until = r_.require(node, "until_error", "discover");
    if (!name || !to || !until) return false;
    step.command = r_.string(*name, "discover command").value_or("");
    const CommandSpec* c = spec.find(step.command);
    if (!c) {
      r_.error(*name, fmt::format("discover: no command '{}' in this file", step.command));
      return false;
    }
    if (c->parameters().size() != 1 || c->request.has_address()) {
      r_.error(*name, fmt::format("discover: {} ('{}') must take the count as its one parameter "
                                  "and no {{addr}}",
                                  c->name, c->request.source()));
      return false;
    }
    if (node["from"]) d.from = r_.integer(node["from"], "discover from", 0, 9999).value_or(1);
    d.to = r_.integer(*to, "discover to", 0, 9999).value_or(d.from);
    if (d.to < d.from || d.to - d.from >= 64) {
      r_.error(*to, fmt::format("discover: 'to' ({}) must be from 'from' ({}) to 63 above it: the "
                                "loop is bounded",
                                d.to, d.from));
      return false;
    }
    for (const auto& [bound, value] : {std::pair{node["from"], d.from}, std::pair{*to, d.to}})
      if (const auto why = argument_problem(*c, 0, value)) {
        r_.error(bound ? bound : *to, fmt::format("discover: {}", *why));
        return false;
      }
    d.until_error = r_.integer(*until, "discover until_error", INT64_MIN, INT64_MAX).value_or(0);
    if (node["error_query"]) {
      d.error_query = r_.string(node["error_query"], "discover error_query").value_or("");
      const CommandSpec* q = spec.find(d.error_query);
      if (!q) {
        r_.error(node["error_query"],
                 fmt::format("discover: no command '{}' in this file", d.error_query));
        return false;
      }
      if (!q->reply || !q->error || !q->parameters().empty() || q->request.has_address()) {
        r_.error(node["error_query"],
                 fmt::format("discover: error_query {} must be a query of the controller's error "
                             "(a reply with an error capture, no parameters, no {{addr}})",
                             q->name));
        return false;
      }
    }
    if (node["nodes"]) d.nodes = r_.boolean(node["nodes"], "discover nodes").value_or(false);
    step.discover = d;
    return true;
  }

  void parse_alignment(const YAML::Node& node, const YAML::Node& root, ProtocolSpec& spec) {
    if (!node) {
      r_.error(root,
               "protocol file: 'alignment' is missing: two or more queries whose replies "
               "differ from one another, which prove the line in step after a failure "
               "(drivers/README.md, \"Proof of alignment\")");
      return;
    }
    if (!r_.expect_sequence(node, "alignment")) return;
    const FieldPattern* previous = nullptr;
    for (const auto& item : node) {
      ProtocolSpec::AlignmentStepSpec step;
      YAML::Node name_node = item;
      if (item.IsMap()) {
        r_.reject_unknown_keys(item, {"command", "error"}, "alignment step");
        if (auto c = r_.require(item, "command", "alignment step"))
          name_node.reset(*c);  // reset: operator= would write into item
        if (auto e = r_.require(item, "error", "alignment step"))
          step.error = r_.integer(*e, "alignment step error", INT64_MIN, INT64_MAX);
        if (step.error && !spec.error_reply) {
          r_.error(item, "alignment: a step that expects an error needs the file's error_reply");
          continue;
        }
      }
      step.command = r_.string(name_node, "alignment step").value_or("");
      const CommandSpec* c = spec.find(step.command);
      if (!c) {
        r_.error(name_node, fmt::format("alignment: no command '{}' in this file", step.command));
        continue;
      }
      if (!c->parameters().empty() || !c->confirm.empty() || (!c->reply && !step.error)) {
        r_.error(name_node,
                 fmt::format("alignment: {} must be a query with a reply and no parameters",
                             step.command));
        continue;
      }
      const FieldPattern* shape = step.error ? &*spec.error_reply : &*c->reply;
      if (previous && same_shape(*previous, *shape))
        r_.error(name_node,
                 fmt::format("alignment: {}'s reply '{}' has the shape of the reply before it, "
                             "'{}', so a late answer to one would pass for the other",
                             step.command, shape->source(), previous->source()));
      previous = shape;
      spec.alignment.push_back(std::move(step));
    }
    if (spec.alignment.size() < 2)
      r_.error(node, "alignment: at least two queries, each reply unlike the one before");
  }

  // Two reply patterns that could answer each other: the same literals and field types.
  static bool same_shape(const FieldPattern& a, const FieldPattern& b) {
    if (a.pieces().size() != b.pieces().size()) return false;
    for (std::size_t i = 0; i < a.pieces().size(); ++i) {
      const auto& x = a.pieces()[i];
      const auto& y = b.pieces()[i];
      if (bool(x.field) != bool(y.field)) return false;
      if (!x.field && x.literal != y.literal) return false;
      if (x.field && (x.field->type != y.field->type || x.field->width != y.field->width))
        return false;
    }
    return true;
  }

  static constexpr std::size_t kMostPrompts = 16;

  YamlReader& r_;
  std::optional<NumberDeclaration> file_numbers_;  // the file's `numbers:`
};

}  // namespace

ProtocolSpecPtr load_protocol_file(const std::string& path, Diagnostics& diagnostics) {
  Diagnostics found;
  auto spec = parse_yaml_file<ProtocolParser>(path, found);
  for (const auto& e : found.errors()) {
    std::string message = e.message;
    if (message.starts_with("YAML syntax:") && e.mark.line > 0) {
      std::ifstream in(path);
      std::string line;
      for (int n = 0; n < e.mark.line && std::getline(in, line);) ++n;
      message += flow_collection_hint(message, line);
    }
    diagnostics.error(e.mark, std::move(message));
  }
  return spec;
}

std::string flow_collection_hint(std::string_view yaml_message, std::string_view line) {
  const bool list = yaml_message.find("sequence flow") != std::string_view::npos;
  const bool map = yaml_message.find("map flow") != std::string_view::npos;
  if (!list && !map) return {};
  // A {placeholder}: a name in braces, as in a template or a model's step.
  bool placeholder = false;
  for (auto open = line.find('{'); open != std::string_view::npos && !placeholder;
       open = line.find('{', open + 1)) {
    auto i = open + 1;
    while (i < line.size() &&
           (std::isalnum(static_cast<unsigned char>(line[i])) || line[i] == '_' || line[i] == ':' ||
            line[i] == '(' || line[i] == ')'))
      ++i;
    placeholder = i > open + 1 && i < line.size() && line[i] == '}';
  }
  if (!placeholder) return {};
  return list ? "; a {placeholder} inside a YAML flow list [...] starts a mapping there: quote the "
                "step or use a block list (one '- ' line per step)"
              : "; a {placeholder} inside a YAML flow mapping {...} starts a mapping there: quote "
                "the text or use a block mapping";
}

void ProtocolLibrary::load_directory(const std::string& directory, Diagnostics& diagnostics) {
  for (const auto& f : yaml_files_in(directory, "protocol", diagnostics)) {
    Diagnostics d;
    auto spec = load_protocol_file(f, d);
    diagnostics.append(d);
    if (spec) add(std::move(spec), diagnostics);
  }
}

void ProtocolLibrary::add(ProtocolSpecPtr spec, Diagnostics& diagnostics) {
  if (const auto it = specs_.find(spec->name); it != specs_.end()) {
    diagnostics.error(
        spec->mark, fmt::format("protocol {} is also defined in {}", spec->name, it->second->file));
    return;
  }
  specs_.emplace(spec->name, std::move(spec));
}

ProtocolSpecPtr ProtocolLibrary::find(std::string_view name) const {
  const auto it = specs_.find(name);
  return it == specs_.end() ? nullptr : it->second;
}

std::vector<ProtocolSpecPtr> ProtocolLibrary::all() const {
  std::vector<ProtocolSpecPtr> out;
  for (const auto& [name, spec] : specs_) out.push_back(spec);
  return out;
}

}  // namespace fieldgate::protocol_file
