#include "sdo_server.hpp"

#include <algorithm>

namespace fieldgate::sim::canopen {

namespace {

// Command specifiers (bits 7..5 of byte 0).
constexpr std::uint8_t kCcsDownloadSegment = 0;
constexpr std::uint8_t kCcsInitiateDownload = 1;
constexpr std::uint8_t kCcsInitiateUpload = 2;
constexpr std::uint8_t kCcsUploadSegment = 3;
constexpr std::uint8_t kCcsAbort = 4;

constexpr std::uint8_t kScsUploadSegment = 0;
constexpr std::uint8_t kScsDownloadSegment = 1;
constexpr std::uint8_t kScsInitiateUpload = 2;
constexpr std::uint8_t kScsInitiateDownload = 3;

std::uint8_t command_specifier(const SdoPayload& p) {
  return p[0] >> 5;
}
std::uint16_t index_of(const SdoPayload& p) {
  return static_cast<std::uint16_t>(p[1] | p[2] << 8);
}

SdoPayload multiplexed(std::uint8_t byte0, std::uint16_t index, std::uint8_t sub) {
  return {
      byte0, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0,
      0};
}

}  // namespace

SdoPayload sdo_abort_payload(std::uint16_t index, std::uint8_t sub, SdoAbort code) {
  SdoPayload p = multiplexed(kCcsAbort << 5, index, sub);
  const auto c = static_cast<std::uint32_t>(code);
  for (int i = 0; i < 4; ++i) p[4 + i] = static_cast<std::uint8_t>(c >> (8 * i));
  return p;
}

const SdoServer::State SdoServer::kIdle{"idle", &SdoServer::idle_recv};
const SdoServer::State SdoServer::kDownloadSegments{"download segments",
                                                    &SdoServer::download_segment_recv};
const SdoServer::State SdoServer::kUploadSegments{"upload segments",
                                                  &SdoServer::upload_segment_recv};

std::optional<SdoPayload> SdoServer::on_request(const SdoPayload& request, TimePoint now) {
  Result result = (this->*state_->on_recv)(request, now);
  state_ = result.next;
  if (state_ != &kIdle) deadline_ = now + timeout_;
  return result.reply;
}

std::optional<SdoPayload> SdoServer::on_time(TimePoint now) {
  if (state_ == &kIdle || now < deadline_) return std::nullopt;
  Result result = abort(SdoAbort::timeout);
  state_ = result.next;
  return result.reply;
}

std::optional<TimePoint> SdoServer::deadline() const {
  if (state_ == &kIdle) return std::nullopt;
  return deadline_;
}

void SdoServer::reset() {
  state_ = &kIdle;
  buffer_.clear();
}

SdoServer::Result SdoServer::abort(SdoAbort code) const {
  return {&kIdle, sdo_abort_payload(index_, sub_, code)};
}

SdoServer::Result SdoServer::idle_recv(const SdoPayload& request, TimePoint now) {
  switch (command_specifier(request)) {
    case kCcsInitiateDownload:
      return initiate_download(request, now);
    case kCcsInitiateUpload:
      return initiate_upload(request, now);
    case kCcsAbort:
      return {&kIdle, std::nullopt};
    case kCcsDownloadSegment:
    case kCcsUploadSegment:
      // No transfer to continue; bytes 1..3 are segment data, not a multiplexer.
      return {&kIdle, sdo_abort_payload(0, 0, SdoAbort::command_specifier)};
    default:  // block transfers (5, 6) and the reserved 7
      return {&kIdle,
              sdo_abort_payload(index_of(request), request[3], SdoAbort::command_specifier)};
  }
}

SdoServer::Result SdoServer::initiate_download(const SdoPayload& request, TimePoint) {
  index_ = index_of(request);
  sub_ = request[3];
  const bool expedited = request[0] & 0x02;
  const bool size_indicated = request[0] & 0x01;

  if (expedited) {
    std::size_t length = 4;
    if (size_indicated) {
      length = 4 - ((request[0] >> 2) & 0x03);
    } else if (const OdEntry* e = od_.find(index_, sub_); e && e->size > 0 && e->size <= 4) {
      length = e->size;
    }
    if (auto a = od_.check_write(index_, sub_, length, size_indicated); a != SdoAbort::none)
      return abort(a);
    if (auto a = od_.write(index_, sub_, std::span(request).subspan(4, length));
        a != SdoAbort::none)
      return abort(a);
    return {&kIdle, multiplexed(kScsInitiateDownload << 5, index_, sub_)};
  }

  size_known_ = size_indicated;
  size_ = size_indicated ? from_le<std::uint32_t>(std::span(request).subspan(4, 4)) : 0;
  if (auto a = od_.check_write(index_, sub_, size_, size_known_); a != SdoAbort::none)
    return abort(a);
  const OdEntry* e = od_.find(index_, sub_);
  max_size_ = e->size > 0 ? e->size : e->max_size;
  toggle_ = false;
  buffer_.clear();
  return {&kDownloadSegments, multiplexed(kScsInitiateDownload << 5, index_, sub_)};
}

std::optional<SdoServer::Result> SdoServer::segment_refused(const SdoPayload& request,
                                                            std::uint8_t expected) const {
  const std::uint8_t ccs = command_specifier(request);
  if (ccs == kCcsAbort) return Result{&kIdle, std::nullopt};
  if (ccs != expected) return abort(SdoAbort::command_specifier);
  const bool toggle = request[0] & 0x10;
  if (toggle != toggle_) return abort(SdoAbort::toggle_bit);
  return std::nullopt;
}

SdoServer::Result SdoServer::download_segment_recv(const SdoPayload& request, TimePoint) {
  if (const auto refused = segment_refused(request, kCcsDownloadSegment)) return *refused;
  const std::size_t n = 7 - ((request[0] >> 1) & 0x07);
  const bool last = request[0] & 0x01;
  buffer_.insert(buffer_.end(), request.begin() + 1, request.begin() + 1 + n);
  if (buffer_.size() > max_size_ || (size_known_ && buffer_.size() > size_))
    return abort(SdoAbort::length_mismatch);

  const SdoPayload ack{static_cast<std::uint8_t>(kScsDownloadSegment << 5 | (toggle_ ? 0x10 : 0)),
                       0,
                       0,
                       0,
                       0,
                       0,
                       0,
                       0};
  toggle_ = !toggle_;
  if (!last) return {&kDownloadSegments, ack};
  if (size_known_ && buffer_.size() != size_) return abort(SdoAbort::length_mismatch);
  if (auto a = od_.write(index_, sub_, buffer_); a != SdoAbort::none) return abort(a);
  buffer_.clear();
  return {&kIdle, ack};
}

SdoServer::Result SdoServer::initiate_upload(const SdoPayload& request, TimePoint) {
  index_ = index_of(request);
  sub_ = request[3];
  Bytes value;
  if (auto a = od_.read(index_, sub_, value); a != SdoAbort::none) return abort(a);

  if (!value.empty() && value.size() <= 4) {
    SdoPayload reply = multiplexed(
        static_cast<std::uint8_t>(kScsInitiateUpload << 5 | (4 - value.size()) << 2 | 0x03), index_,
        sub_);
    std::copy(value.begin(), value.end(), reply.begin() + 4);
    return {&kIdle, reply};
  }
  SdoPayload reply = multiplexed(kScsInitiateUpload << 5 | 0x01, index_, sub_);
  const auto size = static_cast<std::uint32_t>(value.size());
  for (int i = 0; i < 4; ++i) reply[4 + i] = static_cast<std::uint8_t>(size >> (8 * i));
  buffer_ = std::move(value);
  offset_ = 0;
  toggle_ = false;
  return {&kUploadSegments, reply};
}

SdoServer::Result SdoServer::upload_segment_recv(const SdoPayload& request, TimePoint) {
  if (const auto refused = segment_refused(request, kCcsUploadSegment)) return *refused;

  const std::size_t n = std::min<std::size_t>(7, buffer_.size() - offset_);
  const bool last = offset_ + n == buffer_.size();
  SdoPayload reply{};
  reply[0] = static_cast<std::uint8_t>(kScsUploadSegment << 5 | (toggle_ ? 0x10 : 0) |
                                       (7 - n) << 1 | (last ? 0x01 : 0));
  std::copy_n(buffer_.begin() + static_cast<std::ptrdiff_t>(offset_), n, reply.begin() + 1);
  offset_ += n;
  toggle_ = !toggle_;
  if (last) {
    buffer_.clear();
    return {&kIdle, reply};
  }
  return {&kUploadSegments, reply};
}

}  // namespace fieldgate::sim::canopen
