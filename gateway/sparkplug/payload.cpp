#include "gateway/sparkplug/payload.hpp"

#include <chrono>

namespace fieldgate::sparkplug {

uint64_t now_ms() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

Payload make_payload(uint64_t timestamp_ms, std::optional<uint64_t> seq) {
  Payload p;
  p.set_timestamp(timestamp_ms);
  if (seq) p.set_seq(*seq);
  return p;
}

void add_metric(Payload& payload, std::string_view name, DataType type, const MetricValue& value,
                uint64_t timestamp_ms) {
  auto* m = payload.add_metrics();
  m->set_name(std::string(name));
  m->set_timestamp(timestamp_ms);
  m->set_datatype(static_cast<uint32_t>(type));
  if (value.is_null) {
    m->set_is_null(true);
    return;
  }
  switch (type) {
    case DataType::int8:
    case DataType::int16:
    case DataType::int32:
    case DataType::uint16:
    case DataType::uint32:
      m->set_int_value(static_cast<uint32_t>(value.number));
      break;
    case DataType::int64:
    case DataType::uint64:
      m->set_long_value(static_cast<uint64_t>(value.number));
      break;
    case DataType::boolean:
      m->set_boolean_value(value.number != 0);
      break;
    case DataType::string:
      m->set_string_value(value.text);
      break;
  }
}

std::string encode(const Payload& payload) {
  return payload.SerializeAsString();
}

std::optional<Payload> decode(std::string_view bytes) {
  Payload p;
  if (!p.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) return std::nullopt;
  return p;
}

std::optional<int64_t> integer_value(const Metric& metric) {
  if (metric.has_is_null() && metric.is_null()) return std::nullopt;
  switch (metric.value_case()) {
    case Metric::kBooleanValue:
      return metric.boolean_value() ? 1 : 0;
    case Metric::kIntValue: {
      const uint32_t raw = metric.int_value();
      switch (static_cast<DataType>(metric.datatype())) {
        case DataType::int16:
          return static_cast<int16_t>(raw);
        case DataType::int32:
          return static_cast<int32_t>(raw);
        case DataType::int8:
          return static_cast<int8_t>(raw);
        default:
          return raw;
      }
    }
    case Metric::kLongValue:
      if (static_cast<DataType>(metric.datatype()) == DataType::int64)
        return static_cast<int64_t>(metric.long_value());
      if (metric.long_value() > static_cast<uint64_t>(INT64_MAX)) return std::nullopt;
      return static_cast<int64_t>(metric.long_value());
    default:
      return std::nullopt;
  }
}

}  // namespace fieldgate::sparkplug
