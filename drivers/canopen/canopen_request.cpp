#include "drivers/canopen/canopen_request.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <vector>

#include "mapping/yaml_reader.hpp"

namespace fieldgate::canopen {

namespace {

struct Token {
  std::string text;
  bool quoted = false;
};

std::optional<std::vector<Token>> tokenize(std::string_view line, std::string& error) {
  std::vector<Token> out;
  std::size_t i = 0;
  while (i < line.size()) {
    if (line[i] == ' ' || line[i] == '\t') {
      ++i;
      continue;
    }
    Token t;
    if (line[i] == '"') {
      t.quoted = true;
      ++i;
      bool closed = false;
      while (i < line.size()) {
        const char c = line[i++];
        if (c == '"') {
          closed = true;
          break;
        }
        if (c == '\\' && i < line.size()) {
          t.text += line[i++];
          continue;
        }
        t.text += c;
      }
      if (!closed) {
        error = "unterminated string (a closing \" is missing)";
        return std::nullopt;
      }
    } else {
      while (i < line.size() && line[i] != ' ' && line[i] != '\t') t.text += line[i++];
    }
    out.push_back(std::move(t));
  }
  return out;
}

std::optional<std::pair<uint16_t, uint8_t>> parse_index_sub(std::string_view text) {
  const auto colon = text.find(':');
  if (colon == std::string_view::npos) return std::nullopt;
  const auto index = parse_integer_text(text.substr(0, colon));
  const auto sub = parse_integer_text(text.substr(colon + 1));
  if (!index || !sub || *index < 0 || *index > 0xFFFF || *sub < 0 || *sub > 0xFF)
    return std::nullopt;
  return std::pair{static_cast<uint16_t>(*index), static_cast<uint8_t>(*sub)};
}

std::optional<ObjectAddress> object_of_ref(const ObjectRef& ref) {
  const auto type = parse_data_type(ref.data_type);
  if (!type) return std::nullopt;
  return ObjectAddress{ref.index, ref.subindex, *type};
}

// The object a point reads or writes, for steps that name the point.
std::optional<ObjectAddress> object_of_point(const PointDef& p, const Model* model) {
  if (p.read && p.read->object) return object_of_ref(*p.read->object);
  if (p.write && p.write->object) return object_of_ref(*p.write->object);
  if (p.write && !p.write->request.empty()) {
    std::string ignored;
    const std::string text = p.write->request.render([](std::string_view) { return 0; });
    // Not through point names again: only an explicit INDEX:SUB resolves here.
    if (auto op = parse_operation(text, nullptr, ignored); op && op->kind == Operation::Kind::write)
      return op->object;
    (void)model;
  }
  return std::nullopt;
}

// The data type the model gives index:sub, through any point that names the object.
std::optional<DataType> type_from_model(uint16_t index, uint8_t sub, const Model* model) {
  if (!model) return std::nullopt;
  for (const auto& p : model->points)
    if (auto o = object_of_point(p, nullptr); o && o->index == index && o->sub == sub)
      return o->type;
  return std::nullopt;
}

// Parses OBJECT [TYPE] at tokens[pos]; advances pos.
std::optional<ObjectAddress> parse_object(const std::vector<Token>& tokens, std::size_t& pos,
                                          const Model* model, std::string& error) {
  if (pos >= tokens.size()) {
    error = "an object is missing (INDEX:SUB such as 0x6040:0, or a point name)";
    return std::nullopt;
  }
  const std::string& word = tokens[pos].text;
  ++pos;
  std::optional<DataType> explicit_type;
  if (pos < tokens.size() && !tokens[pos].quoted) explicit_type = parse_data_type(tokens[pos].text);
  if (explicit_type) ++pos;
  if (auto is = parse_index_sub(word)) {
    const auto [index, sub] = *is;
    auto type = explicit_type ? explicit_type : type_from_model(index, sub, model);
    if (!type) {
      error = fmt::format(
          "no data type for 0x{:04X}:{}: write it after the object (e.g. 0x{:04X}:{} UNSIGNED16) "
          "or declare the object on a point",
          index, sub, index, sub);
      return std::nullopt;
    }
    return ObjectAddress{index, sub, *type};
  }
  if (word.find(':') != std::string::npos) {
    error = fmt::format("expected INDEX:SUB such as 0x6040:0, found '{}'", word);
    return std::nullopt;
  }
  const PointDef* point = model ? model->find_point(word) : nullptr;
  if (!point) {
    error =
        fmt::format("'{}' is neither INDEX:SUB (such as 0x6040:0) nor a point of the model", word);
    return std::nullopt;
  }
  auto object = object_of_point(*point, model);
  if (!object) {
    error = fmt::format("point '{}' has no CANopen object (read or write 'object')", word);
    return std::nullopt;
  }
  if (explicit_type && *explicit_type != object->type) {
    error = fmt::format("point '{}' is {}, not {}", word, to_string(object->type),
                        to_string(*explicit_type));
    return std::nullopt;
  }
  return object;
}

std::optional<int64_t> integer_token(const std::vector<Token>& tokens, std::size_t pos,
                                     std::string_view what, std::string& error) {
  if (pos >= tokens.size()) {
    error = fmt::format("{} is missing", what);
    return std::nullopt;
  }
  auto v = tokens[pos].quoted ? std::nullopt : parse_integer_text(tokens[pos].text);
  if (!v) error = fmt::format("{}: expected an integer, found '{}'", what, tokens[pos].text);
  return v;
}

constexpr std::string_view kUsage =
    "expected 'read OBJECT', 'write OBJECT VALUE', 'wait OBJECT [& MASK] == VALUE [within "
    "DURATION]' or 'nmt start|stop|pre-operational|reset|reset-communication'";

bool trailing(const std::vector<Token>& tokens, std::size_t pos, std::string& error) {
  if (pos < tokens.size()) {
    error = fmt::format("unexpected '{}' at the end", tokens[pos].text);
    return true;
  }
  return false;
}

// Allowed COB-IDs for a TPDO: not those CiA 301 reserves for NMT, SYNC, EMCY, TIME, SDO,
// heartbeat and LSS.
bool tpdo_cob_allowed(uint32_t id) {
  return (id >= 0x181 && id <= 0x57F) || (id >= 0x680 && id <= 0x6DF);
}

std::optional<TpdoSlot> parse_tpdo(const std::vector<Token>& tokens, std::size_t& pos,
                                   std::string& error) {
  // tpdo COBID byte N
  constexpr std::string_view usage =
      "expected 'tpdo COB-ID byte N' such as 'tpdo 0x180+id byte 2' or 'tpdo 0x1A5 byte 0'";
  if (tokens.size() < pos + 3 || tokens[pos + 1].text != "byte") {
    error = std::string(usage);
    return std::nullopt;
  }
  TpdoSlot slot;
  std::string_view cob = tokens[pos].text;
  if (cob.size() > 3 && cob.substr(cob.size() - 3) == "+id") {
    slot.per_node = true;
    cob.remove_suffix(3);
  }
  const auto id = parse_integer_text(cob);
  const auto offset = parse_integer_text(tokens[pos + 2].text);
  if (!id || !offset || *offset < 0 || *offset > 7) {
    error = std::string(usage);
    return std::nullopt;
  }
  const bool ok = slot.per_node ? tpdo_cob_allowed(static_cast<uint32_t>(*id) + kMinNodeId) &&
                                      tpdo_cob_allowed(static_cast<uint32_t>(*id) + kMaxNodeId)
                                : tpdo_cob_allowed(static_cast<uint32_t>(*id));
  if (*id < 0 || !ok) {
    error = fmt::format(
        "COB-ID {} is not usable for a TPDO (allowed 0x181..0x57F and 0x680..0x6DF for every "
        "node ID)",
        tokens[pos].text);
    return std::nullopt;
  }
  slot.cob_id = static_cast<uint32_t>(*id);
  slot.offset = static_cast<uint8_t>(*offset);
  pos += 3;
  return slot;
}

int point_bytes(ValueType type) {
  return register_count(type) * 2;
}

// Whether every value of the data type fits the point's type (same size with the other sign
// counts too: the bits are shown as they are).
bool type_fits(DataType data, ValueType point) {
  if (point == ValueType::boolean) return data == DataType::boolean || data == DataType::unsigned8;
  return size_of(data) <= static_cast<std::size_t>(point_bytes(point));
}

}  // namespace

std::string to_string(const ObjectAddress& object) {
  return fmt::format("0x{:04X}:{} {}", object.index, object.sub, to_string(object.type));
}

std::optional<Operation> parse_operation(std::string_view text, const Model* model,
                                         std::string& error) {
  auto tokens_opt = tokenize(text, error);
  if (!tokens_opt) return std::nullopt;
  const auto& tokens = *tokens_opt;
  if (tokens.empty()) {
    error = std::string(kUsage);
    return std::nullopt;
  }
  Operation op;
  std::size_t pos = 1;
  const std::string& verb = tokens[0].text;
  if (verb == "read") {
    op.kind = Operation::Kind::read;
    auto o = parse_object(tokens, pos, model, error);
    if (!o) return std::nullopt;
    op.object = *o;
  } else if (verb == "write") {
    op.kind = Operation::Kind::write;
    auto o = parse_object(tokens, pos, model, error);
    if (!o) return std::nullopt;
    op.object = *o;
    if (pos >= tokens.size()) {
      error = "write: the value is missing";
      return std::nullopt;
    }
    if (is_integer(o->type)) {
      auto v = integer_token(tokens, pos, "write value", error);
      if (!v) return std::nullopt;
      if (!in_range(o->type, *v)) {
        error = fmt::format("value {} does not fit {} (range {}..{})", *v, to_string(o->type),
                            min_of(o->type), max_of(o->type));
        return std::nullopt;
      }
      op.value = *v;
    } else {
      if (!tokens[pos].quoted) {
        error = fmt::format("{} takes a quoted string, found '{}'", to_string(o->type),
                            tokens[pos].text);
        return std::nullopt;
      }
      op.text = tokens[pos].text;
    }
    ++pos;
  } else if (verb == "wait") {
    op.kind = Operation::Kind::wait;
    auto o = parse_object(tokens, pos, model, error);
    if (!o) return std::nullopt;
    if (!is_integer(o->type)) {
      error = fmt::format("wait needs an integer object, not {}", to_string(o->type));
      return std::nullopt;
    }
    op.object = *o;
    if (pos < tokens.size() && tokens[pos].text == "&") {
      auto m = integer_token(tokens, pos + 1, "wait mask", error);
      if (!m) return std::nullopt;
      op.mask = static_cast<uint64_t>(*m);
      pos += 2;
    }
    if (pos >= tokens.size() || tokens[pos].text != "==") {
      error = "wait: expected '== VALUE' (e.g. wait statusword & 0x6F == 0x27)";
      return std::nullopt;
    }
    auto v = integer_token(tokens, pos + 1, "wait value", error);
    if (!v) return std::nullopt;
    op.value = *v;
    pos += 2;
    if (pos < tokens.size() && tokens[pos].text == "within") {
      if (pos + 1 >= tokens.size()) {
        error = "wait: a duration must follow 'within' (e.g. within 2s)";
        return std::nullopt;
      }
      auto d = parse_duration_text(tokens[pos + 1].text);
      if (!d || d->count() <= 0) {
        error = fmt::format("wait: '{}' is not a duration (e.g. 500ms, 2s)", tokens[pos + 1].text);
        return std::nullopt;
      }
      op.within = *d;
      pos += 2;
    }
  } else if (verb == "nmt") {
    op.kind = Operation::Kind::nmt;
    if (pos >= tokens.size()) {
      error = "nmt: expected start, stop, pre-operational, reset or reset-communication";
      return std::nullopt;
    }
    const std::string& cmd = tokens[pos].text;
    static constexpr NmtCommand kCommands[] = {
        NmtCommand::start, NmtCommand::stop, NmtCommand::enter_pre_operational,
        NmtCommand::reset_node, NmtCommand::reset_communication};
    const auto* it = std::find_if(std::begin(kCommands), std::end(kCommands),
                                  [&](NmtCommand c) { return to_string(c) == cmd; });
    if (it == std::end(kCommands)) {
      error = fmt::format(
          "nmt: unknown command '{}' (expected start, stop, pre-operational, reset or "
          "reset-communication)",
          cmd);
      return std::nullopt;
    }
    op.nmt = *it;
    ++pos;
  } else {
    error = fmt::format("unknown request '{}': {}", verb, kUsage);
    return std::nullopt;
  }
  if (trailing(tokens, pos, error)) return std::nullopt;
  return op;
}

namespace {

// Whether b is a with its `slot` field (only) changed to `probe`.
bool differs_only_in(const Operation& a, const Operation& b, CompiledOperation::Slot slot,
                     int64_t probe) {
  const bool rest = a.kind == b.kind && a.object == b.object && a.text == b.text &&
                    a.within == b.within && a.nmt == b.nmt;
  if (!rest) return false;
  if (slot == CompiledOperation::Slot::value) return b.value == probe && a.mask == b.mask;
  return b.mask == static_cast<uint64_t>(probe) && a.value == b.value;
}

bool ends_a_token(std::string_view literal) {
  return literal.empty() || literal.back() == ' ' || literal.back() == '\t';
}

// Whether the placeholder at pieces[i] is a whole token: a decimal one alone, a hexadecimal one
// right after "0x"; with a blank or the end after it.
bool whole_token(const std::vector<CommandTemplate::Piece>& pieces, std::size_t i) {
  const auto literal = [&](std::size_t k) -> std::optional<std::string_view> {
    if (k >= pieces.size()) return std::string_view{};
    if (!pieces[k].name.empty()) return std::nullopt;
    return std::string_view(pieces[k].literal);
  };
  const auto before = i == 0 ? std::optional<std::string_view>{""} : literal(i - 1);
  const auto after = literal(i + 1);
  if (!before || !after) return false;
  if (!after->empty() && after->front() != ' ' && after->front() != '\t') return false;
  if (pieces[i].format == 'd') return ends_a_token(*before);
  return before->size() >= 2 && before->substr(before->size() - 2) == "0x" &&
         ends_a_token(before->substr(0, before->size() - 2));
}

}  // namespace

std::shared_ptr<const CompiledOperation> compile_operation(const CommandTemplate& command,
                                                           const Model* model, std::string& error) {
  const auto& pieces = command.pieces();
  // Each placeholder at 1, the others at 0 (values every integer type holds): the field that
  // follows it is the one it fills.
  const auto render = [&](std::size_t which) {
    std::size_t k = 0;
    return command.render([&](std::string_view) { return k++ == which ? 1 : 0; });
  };
  const auto whole = [](const std::string& name) {
    return "{" + name + "} must stand for the whole value written or waited for (or a wait's mask)";
  };
  for (std::size_t i = 0; i < pieces.size(); ++i)
    if (!pieces[i].name.empty() && !whole_token(pieces, i)) {
      error = whole(pieces[i].name);
      return nullptr;
    }
  const auto base = parse_operation(render(pieces.size()), model, error);
  if (!base) return nullptr;
  std::vector<CompiledOperation::Slot> slots;
  std::size_t placeholder = 0;
  for (const auto& piece : pieces) {
    if (piece.name.empty()) continue;
    const auto op = parse_operation(render(placeholder++), model, error);
    if (!op) return nullptr;
    std::optional<CompiledOperation::Slot> slot;
    for (const auto s : {CompiledOperation::Slot::value, CompiledOperation::Slot::mask})
      if (differs_only_in(*base, *op, s, 1)) slot = s;
    if (!slot) {
      error = whole(piece.name);
      return nullptr;
    }
    if (std::find(slots.begin(), slots.end(), *slot) != slots.end()) {
      error = "{" + piece.name + "} fills a field another placeholder fills already";
      return nullptr;
    }
    slots.push_back(*slot);
  }
  return std::make_shared<const CompiledOperation>(*base, std::move(slots));
}

std::optional<Operation> CompiledOperation::with(std::span<const int64_t> arguments,
                                                 std::string& error) const {
  if (arguments.size() != slots_.size()) {
    error = fmt::format("{} values for {} placeholders", arguments.size(), slots_.size());
    return std::nullopt;
  }
  Operation op = operation_;
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    if (slots_[i] == Slot::mask) {
      op.mask = static_cast<uint64_t>(arguments[i]);
      continue;
    }
    op.value = arguments[i];
    if (op.kind == Operation::Kind::write && !in_range(op.object.type, op.value)) {
      error =
          fmt::format("value {} does not fit {} (range {}..{})", op.value,
                      to_string(op.object.type), min_of(op.object.type), max_of(op.object.type));
      return std::nullopt;
    }
  }
  return op;
}

std::optional<PointSource> compile_point_read(const PointDef& point, std::string& error) {
  if (!point.read) {
    error = "the point has no read";
    return std::nullopt;
  }
  const auto& read = *point.read;
  PointSource src;
  src.field = read.field;
  if (read.object) {
    auto type = parse_data_type(read.object->data_type);
    if (!type) {
      error = fmt::format("unknown data type '{}' (known: {})", read.object->data_type,
                          data_type_names());
      return std::nullopt;
    }
    src.object = ObjectAddress{read.object->index, read.object->subindex, *type};
    src.type = *type;
  }
  const std::string request = read.request.source();
  if (!request.empty()) {
    auto tokens_opt = tokenize(request, error);
    if (!tokens_opt) return std::nullopt;
    const auto& tokens = *tokens_opt;
    const auto is = [&](std::initializer_list<std::string_view> words) {
      if (tokens.size() != words.size()) return false;
      std::size_t i = 0;
      for (auto w : words)
        if (tokens[i++].text != w) return false;
      return true;
    };
    if (!tokens.empty() && tokens[0].text == "tpdo") {
      std::size_t pos = 1;
      auto slot = parse_tpdo(tokens, pos, error);
      if (!slot) return std::nullopt;
      src.kind = PointSource::Kind::tpdo;
      src.tpdo = *slot;
      if (pos < tokens.size()) {
        auto type = parse_data_type(tokens[pos].text);
        if (!type) {
          error = fmt::format("tpdo: '{}' is not a data type (known: {})", tokens[pos].text,
                              data_type_names());
          return std::nullopt;
        }
        if (src.object && src.object->type != *type) {
          error = fmt::format("tpdo: the request says {}, the object {}", to_string(*type),
                              to_string(src.object->type));
          return std::nullopt;
        }
        src.type = *type;
        ++pos;
      } else if (!src.object) {
        error = "tpdo: give the data type, after the byte offset or as the point's object";
        return std::nullopt;
      }
      if (trailing(tokens, pos, error)) return std::nullopt;
      if (!is_integer(src.type)) {
        error = fmt::format("a TPDO value must be an integer type, not {}", to_string(src.type));
        return std::nullopt;
      }
      if (src.tpdo.offset + size_of(src.type) > 8) {
        error = fmt::format("{} at byte {} does not fit an 8-byte PDO", to_string(src.type),
                            src.tpdo.offset);
        return std::nullopt;
      }
    } else if (is({"emcy", "code"}) || is({"emcy", "register"}) || is({"nmt", "state"}) ||
               is({"sdo", "abort"})) {
      if (src.object) {
        error = fmt::format("'{}' is kept by the gateway, so the point takes no object", request);
        return std::nullopt;
      }
      src.kind = PointSource::Kind::local;
      src.local = tokens[0].text == "nmt"    ? LocalValue::nmt_state
                  : tokens[0].text == "sdo"  ? LocalValue::sdo_abort
                  : tokens[1].text == "code" ? LocalValue::emcy_code
                                             : LocalValue::emcy_register;
      src.type = src.local == LocalValue::sdo_abort   ? DataType::unsigned32
                 : src.local == LocalValue::emcy_code ? DataType::unsigned16
                                                      : DataType::unsigned8;
    } else {
      error = fmt::format(
          "unknown read request '{}' (expected 'tpdo COB-ID byte N', 'emcy code', 'emcy "
          "register', 'nmt state' or 'sdo abort', or no request with an object)",
          request);
      return std::nullopt;
    }
  } else if (!src.object) {
    error = "read needs an object (e.g. {object: \"0x6064:0\", data_type: INTEGER32})";
    return std::nullopt;
  }
  if (is_integer(src.type)) {
    if (src.field != 0) {
      error = "field applies only to string objects (VISIBLE_STRING, OCTET_STRING)";
      return std::nullopt;
    }
    if (!type_fits(src.type, point.type)) {
      error = fmt::format("{} does not fit a {} point (use a wider type)", to_string(src.type),
                          fieldgate::to_string(point.type));
      return std::nullopt;
    }
  } else if (point.type != ValueType::uint16 && point.type != ValueType::uint32) {
    error = fmt::format(
        "a {} object is shown as characters: the point must be uint16 (2 per point) or uint32 "
        "(4 per point), with field N for the N-th group",
        to_string(src.type));
    return std::nullopt;
  }
  return src;
}

std::optional<int64_t> decode_point_value(const PointSource& source, ValueType type,
                                          std::span<const uint8_t> bytes, std::string& error) {
  if (is_integer(source.type)) {
    auto v = decode_integer(source.type, bytes);
    if (!v) {
      error = fmt::format("{} needs {} bytes, {} arrived", to_string(source.type),
                          size_of(source.type), bytes.size());
      return std::nullopt;
    }
    if (bytes.size() != size_of(source.type)) {
      error = fmt::format("{} needs {} bytes, {} arrived", to_string(source.type),
                          size_of(source.type), bytes.size());
      return std::nullopt;
    }
    return v;
  }
  const auto width = static_cast<std::size_t>(point_bytes(type));
  uint64_t v = 0;
  for (std::size_t i = 0; i < width; ++i) {
    const std::size_t at = static_cast<std::size_t>(source.field) * width + i;
    v = (v << 8) | (at < bytes.size() ? bytes[at] : 0);
  }
  return static_cast<int64_t>(v);
}

std::optional<int64_t> decode_tpdo_value(const PointSource& source, const CanFrame& frame,
                                         std::string& error) {
  const std::size_t end = source.tpdo.offset + size_of(source.type);
  if (frame.len < end) {
    error = fmt::format("PDO 0x{:03X} has {} bytes, the model maps {} up to byte {}", frame.id,
                        frame.len, to_string(source.type), end);
    return std::nullopt;
  }
  return decode_integer(
      source.type,
      std::span<const uint8_t>(frame.data).subspan(source.tpdo.offset, size_of(source.type)));
}

}  // namespace fieldgate::canopen
