#pragma once
// A gRPC call written by hand for a raw TCP connection (raw_connection.h), for a client no gRPC
// library is: one that announces a flow-control window of 0 bytes, so the server can send the
// headers of its answer but not one byte of a message — a WatchJob stream that is never read,
// however patient the server is. HTTP/2 (RFC 9113) frames and HPACK (RFC 7541) literals, enough
// for one call on stream 1.
#include <cstdint>
#include <string>

#include "tests/util/raw_connection.h"

namespace pf::test_util {

// One HTTP/2 frame: 24-bit length, type, flags, 31-bit stream id, payload.
inline std::string Http2Frame(uint8_t type, uint8_t flags, uint32_t stream, const std::string& payload) {
  std::string f;
  const uint32_t n = uint32_t(payload.size());
  f += char((n >> 16) & 0xff);
  f += char((n >> 8) & 0xff);
  f += char(n & 0xff);
  f += char(type);
  f += char(flags);
  for (int shift = 24; shift >= 0; shift -= 8) f += char((stream >> shift) & 0xff);
  return f + payload;
}

// An HPACK integer with an N-bit prefix (RFC 7541 §5.1); `first` holds the bits above the prefix.
inline std::string HpackInteger(uint64_t value, int prefix_bits, uint8_t first = 0) {
  const uint64_t limit = (uint64_t(1) << prefix_bits) - 1;
  std::string out;
  if (value < limit) return out + char(first | uint8_t(value));
  out += char(first | uint8_t(limit));
  for (value -= limit; value >= 128; value >>= 7) out += char(0x80 | (value & 0x7f));
  return out + char(value);
}

// "Literal header field without indexing — new name" (RFC 7541 §6.2.2), no Huffman coding.
inline std::string HpackLiteral(const std::string& name, const std::string& value) {
  return std::string(1, '\0') + HpackInteger(name.size(), 7) + name + HpackInteger(value.size(), 7) + value;
}

// The client's bytes of one gRPC call of `method` ("/pkg.Service/Method") with the serialized
// request `message`: the connection preface, SETTINGS with SETTINGS_INITIAL_WINDOW_SIZE =
// `stream_window` (0: the server may send no DATA on the stream), an acknowledgement of the
// server's SETTINGS, HEADERS and the request as one DATA frame that ends the stream.
inline std::string GrpcCallBytes(const std::string& authority, const std::string& method,
                                 const std::string& message, uint32_t stream_window,
                                 const std::string& authorization = "") {
  std::string out = "PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n";
  std::string settings;
  settings += char(0);
  settings += char(4);  // SETTINGS_INITIAL_WINDOW_SIZE
  for (int shift = 24; shift >= 0; shift -= 8) settings += char((stream_window >> shift) & 0xff);
  out += Http2Frame(0x4, 0, 0, settings);
  out += Http2Frame(0x4, 0x1, 0, "");  // ACK
  std::string headers = HpackLiteral(":method", "POST") + HpackLiteral(":scheme", "http") +
                        HpackLiteral(":path", method) + HpackLiteral(":authority", authority) +
                        HpackLiteral("content-type", "application/grpc") + HpackLiteral("te", "trailers");
  if (!authorization.empty()) headers += HpackLiteral("authorization", authorization);
  out += Http2Frame(0x1, 0x4, 1, headers);  // END_HEADERS
  std::string data(1, '\0');                // not compressed
  const uint32_t n = uint32_t(message.size());
  for (int shift = 24; shift >= 0; shift -= 8) data += char((n >> shift) & 0xff);
  out += Http2Frame(0x0, 0x1, 1, data + message);  // END_STREAM
  return out;
}

// Reads the server's frames (SETTINGS, PING, WINDOW_UPDATE, …: never a message, the window being
// 0) until the HEADERS of stream 1 and returns their flags — END_STREAM (0x1) set: a trailers-only
// answer, the call was refused — or -1 if none arrived within `seconds` per frame.
inline int ResponseHeadersFlags(RawConnection& connection, double seconds = 5) {
  for (;;) {
    const std::string head = connection.ReceiveExactly(9, seconds);
    if (head.size() < 9) return -1;
    const auto byte = [&](size_t i) { return uint32_t(static_cast<unsigned char>(head[i])); };
    const uint32_t length = byte(0) << 16 | byte(1) << 8 | byte(2);
    const uint32_t stream = (byte(5) & 0x7f) << 24 | byte(6) << 16 | byte(7) << 8 | byte(8);
    if (connection.ReceiveExactly(length, seconds).size() < length) return -1;
    if (byte(3) == 0x1 && stream == 1) return int(byte(4));
  }
}

}  // namespace pf::test_util
