#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "sparkplug_b.pb.h"

namespace fieldgate::sparkplug {

using Payload = org::eclipse::tahu::protobuf::Payload;
using Metric = org::eclipse::tahu::protobuf::Payload::Metric;

// Sparkplug B data types used here (specification 6.4.16).
enum class DataType : uint32_t {
  int8 = 1,
  int16 = 2,
  int32 = 3,
  int64 = 4,
  uint16 = 6,
  uint32 = 7,
  uint64 = 8,
  boolean = 11,
  string = 12,
};

// A metric's value as the gateway holds it: integers travel as int64 (as in the process image).
struct MetricValue {
  bool is_null = false;
  int64_t number = 0;  // integer types and Boolean (0/1)
  std::string text;    // String
  bool operator==(const MetricValue&) const = default;
};

uint64_t now_ms();
Payload make_payload(uint64_t timestamp_ms, std::optional<uint64_t> seq);
// Appends a metric; the value goes in the field the specification gives the type (int_value for
// the 8-32 bit types, two's complement for signed ones; long_value for 64 bit).
void add_metric(Payload& payload, std::string_view name, DataType type, const MetricValue& value,
                uint64_t timestamp_ms);
std::string encode(const Payload& payload);
std::optional<Payload> decode(std::string_view bytes);
// A command metric's value as an integer of the declared type, booleans as 0/1; nullopt for a
// null or non-integer value.
std::optional<int64_t> integer_value(const Metric& metric);

}  // namespace fieldgate::sparkplug
