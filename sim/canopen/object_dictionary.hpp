// CiA 301 object dictionary of one simulated node: entries addressed by index:subindex, each
// with an access type, a size and read/write functions bound to the node's state.
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace fieldgate::sim::canopen {

// SDO abort codes (CiA 301 table 22) the simulator produces.
enum class SdoAbort : std::uint32_t {
  none = 0,
  toggle_bit = 0x05030000,
  timeout = 0x05040000,
  command_specifier = 0x05040001,
  write_only = 0x06010001,  // read of a write-only object
  read_only = 0x06010002,   // write to a read-only or constant object
  no_object = 0x06020000,
  length_mismatch = 0x06070010,
  no_subindex = 0x06090011,
  value_range = 0x06090030,
  value_too_low = 0x06090032,
  device_state = 0x08000022,
};

enum class Access { ro, wo, rw, constant };

using Bytes = std::vector<std::uint8_t>;

struct OdEntry {
  std::string name;
  Access access = Access::ro;
  std::size_t size = 0;      // bytes of a fixed-size value; 0 for strings and domains
  std::size_t max_size = 0;  // longest string or domain a download may write
  std::function<Bytes()> read;
  std::function<SdoAbort(std::span<const std::uint8_t>)> write;

  bool readable() const { return access != Access::wo; }
  bool writable() const { return access == Access::wo || access == Access::rw; }
};

template <class T>
Bytes to_le(T value) {
  static_assert(std::is_integral_v<T>);
  Bytes out(sizeof(T));
  auto u = static_cast<std::make_unsigned_t<T>>(value);
  for (std::size_t i = 0; i < sizeof(T); ++i) out[i] = static_cast<std::uint8_t>(u >> (8 * i));
  return out;
}

template <class T>
T from_le(std::span<const std::uint8_t> bytes) {
  static_assert(std::is_integral_v<T>);
  std::make_unsigned_t<T> u = 0;
  for (std::size_t i = 0; i < sizeof(T) && i < bytes.size(); ++i)
    u |= static_cast<std::make_unsigned_t<T>>(static_cast<std::make_unsigned_t<T>>(bytes[i])
                                              << (8 * i));
  return static_cast<T>(u);
}

class ObjectDictionary {
 public:
  void add(std::uint16_t index, std::uint8_t sub, OdEntry entry);

  // An integer bound to a variable that outlives the dictionary. on_write, when given,
  // validates and applies a downloaded value; otherwise the value is stored as is.
  template <class T>
  void add_value(std::uint16_t index, std::uint8_t sub, std::string name, Access access, T& var,
                 std::function<SdoAbort(T)> on_write = {}) {
    OdEntry e;
    e.name = std::move(name);
    e.access = access;
    e.size = sizeof(T);
    e.read = [&var] { return to_le(var); };
    e.write = [&var, on_write](std::span<const std::uint8_t> data) {
      const T value = from_le<T>(data);
      if (on_write) return on_write(value);
      var = value;
      return SdoAbort::none;
    };
    add(index, sub, std::move(e));
  }

  template <class T>
  void add_const(std::uint16_t index, std::uint8_t sub, std::string name, T value) {
    OdEntry e;
    e.name = std::move(name);
    e.access = Access::constant;
    e.size = sizeof(T);
    e.read = [value] { return to_le(value); };
    add(index, sub, std::move(e));
  }

  // A VISIBLE_STRING; writable when max_size > 0.
  void add_string(std::uint16_t index, std::uint8_t sub, std::string name, std::string& var,
                  std::size_t max_size = 0);

  const OdEntry* find(std::uint16_t index, std::uint8_t sub) const;
  // no_object when the index is unknown, no_subindex when only the subindex is.
  SdoAbort lookup(std::uint16_t index, std::uint8_t sub, const OdEntry*& entry) const;

  SdoAbort read(std::uint16_t index, std::uint8_t sub, Bytes& out) const;
  // Checks access and, when known, the length before any data is transferred.
  SdoAbort check_write(std::uint16_t index, std::uint8_t sub, std::size_t length,
                       bool length_known) const;
  SdoAbort write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data);

  std::size_t size() const { return entries_.size(); }

 private:
  static std::uint32_t key(std::uint16_t index, std::uint8_t sub) {
    return static_cast<std::uint32_t>(index) << 8 | sub;
  }
  std::map<std::uint32_t, OdEntry> entries_;
};

}  // namespace fieldgate::sim::canopen
