#include "object_dictionary.hpp"

#include <stdexcept>

namespace fieldgate::sim::canopen {

void ObjectDictionary::add(std::uint16_t index, std::uint8_t sub, OdEntry entry) {
  if (!entries_.emplace(key(index, sub), std::move(entry)).second)
    throw std::logic_error("object dictionary entry defined twice");
}

void ObjectDictionary::add_string(std::uint16_t index, std::uint8_t sub, std::string name,
                                  std::string& var, std::size_t max_size) {
  OdEntry e;
  e.name = std::move(name);
  e.access = max_size > 0 ? Access::rw : Access::constant;
  e.max_size = max_size;
  e.read = [&var] { return Bytes(var.begin(), var.end()); };
  e.write = [&var](std::span<const std::uint8_t> data) {
    var.assign(data.begin(), data.end());
    return SdoAbort::none;
  };
  add(index, sub, std::move(e));
}

const OdEntry* ObjectDictionary::find(std::uint16_t index, std::uint8_t sub) const {
  const auto it = entries_.find(key(index, sub));
  return it == entries_.end() ? nullptr : &it->second;
}

SdoAbort ObjectDictionary::lookup(std::uint16_t index, std::uint8_t sub,
                                  const OdEntry*& entry) const {
  entry = find(index, sub);
  if (entry) return SdoAbort::none;
  const auto it = entries_.lower_bound(key(index, 0));
  if (it != entries_.end() && (it->first >> 8) == index) return SdoAbort::no_subindex;
  return SdoAbort::no_object;
}

SdoAbort ObjectDictionary::read(std::uint16_t index, std::uint8_t sub, Bytes& out) const {
  const OdEntry* e = nullptr;
  if (auto abort = lookup(index, sub, e); abort != SdoAbort::none) return abort;
  if (!e->readable()) return SdoAbort::write_only;
  out = e->read();
  return SdoAbort::none;
}

SdoAbort ObjectDictionary::check_write(std::uint16_t index, std::uint8_t sub, std::size_t length,
                                       bool length_known) const {
  const OdEntry* e = nullptr;
  if (auto abort = lookup(index, sub, e); abort != SdoAbort::none) return abort;
  if (!e->writable()) return SdoAbort::read_only;
  if (length_known) {
    if (e->size > 0 && length != e->size) return SdoAbort::length_mismatch;
    if (e->size == 0 && length > e->max_size) return SdoAbort::length_mismatch;
  }
  return SdoAbort::none;
}

SdoAbort ObjectDictionary::write(std::uint16_t index, std::uint8_t sub,
                                 std::span<const std::uint8_t> data) {
  if (auto abort = check_write(index, sub, data.size(), true); abort != SdoAbort::none)
    return abort;
  return find(index, sub)->write(data);
}

}  // namespace fieldgate::sim::canopen
