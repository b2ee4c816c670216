#include "drivers/canopen/sdo_client.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace fieldgate::canopen {

namespace {
// Server command specifiers (byte 0, bits 7..5).
constexpr uint8_t kScsUploadSegment = 0;
constexpr uint8_t kScsDownloadSegment = 1;
constexpr uint8_t kScsInitiateUpload = 2;
constexpr uint8_t kScsInitiateDownload = 3;
constexpr uint8_t kScsAbort = 4;

uint8_t scs(const SdoPayload& p) {
  return static_cast<uint8_t>(p[0] >> 5);
}
bool toggle_of(const SdoPayload& p) {
  return (p[0] & 0x10) != 0;
}
}  // namespace

const SdoClient::State SdoClient::kIdle{"idle", &SdoClient::idle_recv};
const SdoClient::State SdoClient::kUploadInitiate{"upload initiate",
                                                  &SdoClient::upload_initiate_recv};
const SdoClient::State SdoClient::kUploadSegment{"upload segment", &SdoClient::upload_segment_recv};
const SdoClient::State SdoClient::kDownloadInitiate{"download initiate",
                                                    &SdoClient::download_initiate_recv};
const SdoClient::State SdoClient::kDownloadSegment{"download segment",
                                                   &SdoClient::download_segment_recv};

SdoClient::SdoClient(uint8_t node, std::chrono::microseconds timeout)
    : node_(node), timeout_(timeout) {}

std::optional<TimePoint> SdoClient::deadline() const {
  if (idle()) return std::nullopt;
  return deadline_;
}

SdoStep SdoClient::upload(uint16_t index, uint8_t sub, TimePoint now) {
  if (!idle()) return busy();
  begin(index, sub, {});
  return request(kUploadInitiate, sdo_upload_request(index, sub), now);
}

SdoStep SdoClient::download(uint16_t index, uint8_t sub, std::vector<uint8_t> data, TimePoint now) {
  if (!idle()) return busy();
  begin(index, sub, std::move(data));
  return request(kDownloadInitiate, sdo_download_request(index, sub, data_), now);
}

SdoStep SdoClient::busy() const {
  // The running transfer goes on: this one fails without touching it.
  return {std::nullopt, failure(SdoResult::Status::client_abort, sdo_abort::general,
                                "an SDO transfer to this node is already running")};
}

void SdoClient::begin(uint16_t index, uint8_t sub, std::vector<uint8_t> data) {
  index_ = index;
  sub_ = sub;
  toggle_ = false;
  size_.reset();
  data_ = std::move(data);
  offset_ = 0;
}

SdoStep SdoClient::on_frame(const CanFrame& frame, TimePoint now) {
  if (frame.error || frame.rtr || frame.id != cob::sdo_tx + node_) return {};
  // CiA 301 SDO frames always have 8 bytes; like the common stacks, ignore anything shorter.
  if (frame.len != 8) {
    ++ignored_;
    return {};
  }
  return (this->*state_->on_recv)(frame.data, now);
}

SdoStep SdoClient::on_time(TimePoint now) {
  if (idle() || now < deadline_) return {};
  return end(SdoResult::Status::timeout, sdo_abort::timeout,
             fmt::format("no SDO response from node {} within {} ms ({} of 0x{:04X}:{})", node_,
                         std::chrono::duration_cast<std::chrono::milliseconds>(timeout_).count(),
                         state_->name, index_, sub_),
             Tell::server);
}

SdoStep SdoClient::abort(uint32_t code) {
  if (idle()) return {};
  return client_abort(code, abort_text(code));
}

bool SdoClient::same_object(const SdoPayload& response) const {
  return sdo_index(response) == index_ && sdo_subindex(response) == sub_;
}

SdoStep SdoClient::request(const State& next, const SdoPayload& payload, TimePoint now) {
  state_ = &next;
  deadline_ = now + timeout_;
  return {sdo_request_frame(node_, payload), std::nullopt};
}

SdoStep SdoClient::finish(SdoResult result, std::optional<CanFrame> send) {
  state_ = &kIdle;
  if (result.status == SdoResult::Status::ok) result.data = std::move(data_);
  data_.clear();
  return {std::move(send), std::move(result)};
}

SdoStep SdoClient::finish_ok() {
  return finish(SdoResult{});
}

SdoResult SdoClient::failure(SdoResult::Status status, uint32_t code, std::string text) {
  SdoResult r;
  r.status = status;
  r.abort_code = code;
  r.text = std::move(text);
  return r;
}

SdoStep SdoClient::end(SdoResult::Status status, uint32_t code, std::string text, Tell tell) {
  std::optional<CanFrame> send;
  if (tell == Tell::server) send = sdo_request_frame(node_, sdo_abort_request(index_, sub_, code));
  return finish(failure(status, code, std::move(text)), std::move(send));
}

SdoStep SdoClient::server_abort(const SdoPayload& response) {
  const uint32_t code = sdo_u32(response);
  return end(SdoResult::Status::server_abort, code,
             fmt::format("SDO abort 0x{:08X} from node {} for 0x{:04X}:{}: {}", code, node_, index_,
                         sub_, abort_text(code)),
             Tell::nobody);
}

SdoStep SdoClient::client_abort(uint32_t code, std::string why) {
  return end(SdoResult::Status::client_abort, code,
             fmt::format("SDO transfer with node {} for 0x{:04X}:{} aborted by the gateway: {}",
                         node_, index_, sub_, why),
             Tell::server);
}

SdoStep SdoClient::idle_recv(const SdoPayload&, TimePoint) {
  ++ignored_;
  return {};
}

// What every response is checked for first: the server's abort of this transfer (one naming
// another object is a late answer to an earlier transfer, and ignored), or a command specifier
// other than the one `request` expects.
std::optional<SdoStep> SdoClient::screen(const SdoPayload& response, uint8_t expected,
                                         std::string_view request, TimePoint now) {
  const uint8_t cs = scs(response);
  if (cs == kScsAbort)
    return same_object(response) ? server_abort(response) : idle_recv(response, now);
  if (cs != expected)
    return client_abort(sdo_abort::command_specifier,
                        fmt::format("unexpected response 0x{:02X} to {}", response[0], request));
  return std::nullopt;
}

SdoStep SdoClient::toggle_mismatch() {
  return client_abort(sdo_abort::toggle_bit, fmt::format("toggle bit {} where {} was due",
                                                         toggle_ ? 0 : 1, toggle_ ? 1 : 0));
}

SdoStep SdoClient::upload_initiate_recv(const SdoPayload& response, TimePoint now) {
  if (auto refused = screen(response, kScsInitiateUpload, "an upload request", now))
    return std::move(*refused);
  if (!same_object(response)) return idle_recv(response, now);  // a late answer to another
  const bool expedited = response[0] & 0x02;
  const bool size_indicated = response[0] & 0x01;
  if (expedited) {
    const std::size_t n = size_indicated ? 4 - ((response[0] >> 2) & 0x03) : 4;
    data_.assign(response.begin() + 4, response.begin() + 4 + static_cast<std::ptrdiff_t>(n));
    return finish_ok();
  }
  if (size_indicated) {
    size_ = sdo_u32(response);
    if (*size_ > kMaxUpload)
      return client_abort(sdo_abort::out_of_memory,
                          fmt::format("the server announced {} bytes, more than the {} the "
                                      "gateway accepts",
                                      *size_, kMaxUpload));
  }
  toggle_ = false;
  return request(kUploadSegment, sdo_upload_segment_request(toggle_), now);
}

SdoStep SdoClient::upload_segment_recv(const SdoPayload& response, TimePoint now) {
  if (auto refused = screen(response, kScsUploadSegment, "an upload segment request", now))
    return std::move(*refused);
  if (toggle_of(response) != toggle_) return toggle_mismatch();
  const std::size_t n = 7 - ((response[0] >> 1) & 0x07);
  const bool last = response[0] & 0x01;
  data_.insert(data_.end(), response.begin() + 1,
               response.begin() + 1 + static_cast<std::ptrdiff_t>(n));
  if ((size_ && data_.size() > *size_) || data_.size() > kMaxUpload)
    return client_abort(sdo_abort::length_too_high,
                        fmt::format("the server sent more than the {} bytes it announced",
                                    size_.value_or(kMaxUpload)));
  if (!last) {
    toggle_ = !toggle_;
    return request(kUploadSegment, sdo_upload_segment_request(toggle_), now);
  }
  if (size_ && data_.size() != *size_) {
    // The server has ended the transfer, so there is nobody left to send an abort to.
    return end(SdoResult::Status::client_abort, sdo_abort::length_too_low,
               fmt::format("node {} sent {} bytes of 0x{:04X}:{} but announced {}", node_,
                           data_.size(), index_, sub_, *size_),
               Tell::nobody);
  }
  return finish_ok();
}

SdoStep SdoClient::download_initiate_recv(const SdoPayload& response, TimePoint now) {
  if (auto refused = screen(response, kScsInitiateDownload, "a download request", now))
    return std::move(*refused);
  if (!same_object(response)) return idle_recv(response, now);
  if (!data_.empty() && data_.size() <= 4) return finish_ok();  // expedited: done
  toggle_ = false;
  return next_download_segment(now);
}

SdoStep SdoClient::next_download_segment(TimePoint now) {
  const std::size_t n = std::min<std::size_t>(7, data_.size() - offset_);
  const bool last = offset_ + n >= data_.size();
  const auto payload =
      sdo_download_segment(toggle_, std::span<const uint8_t>(data_).subspan(offset_, n), last);
  offset_ += n;
  return request(kDownloadSegment, payload, now);
}

SdoStep SdoClient::download_segment_recv(const SdoPayload& response, TimePoint now) {
  if (auto refused = screen(response, kScsDownloadSegment, "a download segment", now))
    return std::move(*refused);
  if (toggle_of(response) != toggle_) return toggle_mismatch();
  if (offset_ >= data_.size()) return finish_ok();
  toggle_ = !toggle_;
  return next_download_segment(now);
}

}  // namespace fieldgate::canopen
