#include "mapping/register_map_document.hpp"

#include <fmt/format.h>

namespace fieldgate {

std::string modicon_reference(Table table, uint16_t address) {
  const int prefix = table == Table::coils             ? 0
                     : table == Table::discrete_inputs ? 1
                     : table == Table::input_registers ? 3
                                                       : 4;
  const unsigned number = address + 1u;
  if (number <= 9999) return fmt::format("{}{:04}", prefix, number);
  return fmt::format("{}{:05}", prefix, number);
}

namespace {

struct Row {
  std::string table;
  uint16_t address;
  std::string reference;
  std::string name;
  std::string type;
  std::string word_order;
  std::string units;
  std::string scale;
  std::string access;
  std::string description;
};

std::string access_of(Table table, const RegisterEntry& e, const Model& model) {
  if (table == Table::input_registers || table == Table::discrete_inputs) return "R";
  if (e.kind == RegisterEntry::Kind::point)
    return model.points[static_cast<std::size_t>(e.index)].readable() ? "R/W" : "W";
  return e.writable ? "R/W" : "R";
}

std::vector<Row> rows_of(const UnitMap& unit, WordOrder order) {
  std::vector<Row> rows;
  for (int t = 0; t < 4; ++t) {
    const auto table = static_cast<Table>(t);
    for (const auto& e : unit.tables[static_cast<std::size_t>(t)]) {
      Row r;
      r.table = std::string(to_string(table));
      r.address = e.address;
      r.reference = modicon_reference(table, e.address);
      if (e.count > 1)
        r.reference +=
            "-" + modicon_reference(table, static_cast<uint16_t>(e.address + e.count - 1));
      r.name = e.name;
      r.type = std::string(to_string(e.type));
      r.word_order = e.count > 1 ? std::string(to_string(order)) : "";
      r.units = e.units;
      r.scale = e.scale == 1.0 ? "" : fmt::format("{}", e.scale);
      r.access = access_of(table, e, *unit.model);
      r.description = e.description;
      if (e.kind == RegisterEntry::Kind::point_bit) r.description = fmt::format("bit {}", e.bit);
      rows.push_back(std::move(r));
    }
  }
  return rows;
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (const char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string md_cell(const std::string& s) {
  std::string out;
  for (const char c : s)
    out += c == '|' ? std::string("\\|") : c == '\n' ? std::string(" ") : std::string(1, c);
  return out;
}

constexpr const char* kCsvHeader =
    "unit,node,bus,model,table,address,reference,name,type,word_order,units,scale,access,"
    "description\n";

// prefix: the listener column ("NAME,") or nothing.
void append_csv_rows(std::string& out, const RegisterMap& map, const std::string& prefix) {
  for (const auto& [id, unit] : map.units())
    for (const auto& r : rows_of(unit, map.word_order()))
      out += fmt::format("{}{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", prefix, id,
                         csv_field(unit.node_name), csv_field(unit.bus_name),
                         csv_field(unit.model->name), csv_field(r.table), r.address, r.reference,
                         csv_field(r.name), r.type, r.word_order, csv_field(r.units), r.scale,
                         r.access, csv_field(r.description));
}

}  // namespace

std::string write_register_map_document(const RegisterMap& map, DocumentFormat format) {
  std::string out;
  if (format == DocumentFormat::csv) {
    out += kCsvHeader;
    append_csv_rows(out, map, "");
    return out;
  }
  out +=
      "# Register map\n\nAddresses are 0-based as sent on the wire; the reference column gives "
      "the 1-based Modicon notation. 32-bit values take two registers, word order as shown.\n";
  for (const auto& [id, unit] : map.units()) {
    out += fmt::format("\n## Unit {}: {} (bus {}, model {})\n\n", id, unit.node_name, unit.bus_name,
                       unit.model->name);
    if (!unit.model->description.empty()) out += md_cell(unit.model->description) + "\n\n";
    out +=
        "| table | address | reference | name | type | word order | units | scale | access | "
        "description |\n|---|---|---|---|---|---|---|---|---|---|\n";
    for (const auto& r : rows_of(unit, map.word_order()))
      out += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", r.table,
                         r.address, r.reference, md_cell(r.name), r.type, r.word_order,
                         md_cell(r.units), r.scale, r.access, md_cell(r.description));
    if (!unit.model->actions.empty()) {
      out += fmt::format(
          "\nActions (write the code to holding register {}; status in {}):\n\n"
          "| code | action | description |\n|---|---|---|\n",
          layout::action_block, layout::action_block + 1);
      for (const auto& a : unit.model->actions)
        out += fmt::format("| {} | {} | {}{} |\n", a.code, a.name, md_cell(a.description),
                           a.bus_wide ? " (affects every node on the bus)" : "");
    }
  }
  return out;
}

std::string write_register_map_document(const std::vector<ListenerMap>& listeners,
                                        DocumentFormat format) {
  if (listeners.size() == 1) return write_register_map_document(*listeners[0].map, format);
  std::string out;
  if (format == DocumentFormat::csv) {
    out += std::string("listener,") + kCsvHeader;
    for (const auto& l : listeners) append_csv_rows(out, *l.map, csv_field(l.name) + ",");
    return out;
  }
  out +=
      "# Modbus listeners\n\nEach listener is its own Modbus TCP endpoint with its own unit IDs "
      "1..247.\n\n| listener | endpoint | units |\n|---|---|---|\n";
  for (const auto& l : listeners)
    out += fmt::format("| {} | {} | {} |\n", md_cell(l.name), l.endpoint, l.map->units().size());
  for (const auto& l : listeners) {
    std::string doc = write_register_map_document(*l.map, format);
    // Each listener's document one level down, under its own heading.
    std::string shifted;
    std::size_t line = 0;
    while (line < doc.size()) {
      const auto end = doc.find('\n', line);
      const auto text = doc.substr(line, end == std::string::npos ? end : end - line);
      shifted += (text.starts_with("#") ? "#" + text : text) + "\n";
      line = end == std::string::npos ? doc.size() : end + 1;
    }
    out += fmt::format("\n# Listener {} ({})\n\n", l.name, l.endpoint) +
           shifted.substr(shifted.find('\n') + 1);  // without the per-listener title
  }
  return out;
}

}  // namespace fieldgate
