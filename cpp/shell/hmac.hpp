// SHA-256 (FIPS 180-4) and HMAC-SHA256 (RFC 2104), header-only, no
// dependencies: the optional message authentication of the bench's LCM
// messages (docs/PROTOCOL.md, "Authentication"). Checked against the
// FIPS 180-4 examples and RFC 4231's test vectors through the binding
// (_core.hmac_sha256, _core.sha256; tests/test_auth.py).
#pragma once
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

namespace sc_rt {

class Sha256 {
 public:
  using Digest = std::array<uint8_t, 32>;
  Sha256() { reset(); }
  void reset() {
    static const uint32_t h0[8] = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                                   0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
    std::memcpy(h_, h0, sizeof h_);
    len_ = 0;
    fill_ = 0;
  }
  void update(const void* data, std::size_t n) {
    const uint8_t* p = static_cast<const uint8_t*>(data);
    len_ += uint64_t(n);
    while (n > 0) {
      const std::size_t take = std::min<std::size_t>(64 - fill_, n);
      std::memcpy(buf_ + fill_, p, take);
      fill_ += take;
      p += take;
      n -= take;
      if (fill_ == 64) {
        block(buf_);
        fill_ = 0;
      }
    }
  }
  Digest finish() {
    const uint64_t bits = len_ * 8;
    const uint8_t pad = 0x80;
    update(&pad, 1);
    const uint8_t zero = 0;
    while (fill_ != 56) update(&zero, 1);
    uint8_t l[8];
    for (int i = 0; i < 8; ++i) l[i] = uint8_t(bits >> (56 - 8 * i));
    update(l, 8);
    Digest d;
    for (int i = 0; i < 8; ++i)
      for (int j = 0; j < 4; ++j) d[4 * i + j] = uint8_t(h_[i] >> (24 - 8 * j));
    reset();
    return d;
  }
  static Digest of(const void* data, std::size_t n) {
    Sha256 s;
    s.update(data, n);
    return s.finish();
  }

 private:
  static uint32_t rotr(uint32_t x, int n) { return (x >> n) | (x << (32 - n)); }
  void block(const uint8_t* b) {
    static const uint32_t k[64] = {
        0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
        0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
        0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
        0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
        0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
        0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
        0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
        0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};
    uint32_t w[64];
    for (int i = 0; i < 16; ++i)
      w[i] = uint32_t(b[4 * i]) << 24 | uint32_t(b[4 * i + 1]) << 16 | uint32_t(b[4 * i + 2]) << 8 |
             uint32_t(b[4 * i + 3]);
    for (int i = 16; i < 64; ++i) {
      const uint32_t s0 = rotr(w[i - 15], 7) ^ rotr(w[i - 15], 18) ^ (w[i - 15] >> 3);
      const uint32_t s1 = rotr(w[i - 2], 17) ^ rotr(w[i - 2], 19) ^ (w[i - 2] >> 10);
      w[i] = w[i - 16] + s0 + w[i - 7] + s1;
    }
    uint32_t a = h_[0], bb = h_[1], c = h_[2], d = h_[3], e = h_[4], f = h_[5], g = h_[6], h = h_[7];
    for (int i = 0; i < 64; ++i) {
      const uint32_t S1 = rotr(e, 6) ^ rotr(e, 11) ^ rotr(e, 25);
      const uint32_t ch = (e & f) ^ (~e & g);
      const uint32_t t1 = h + S1 + ch + k[i] + w[i];
      const uint32_t S0 = rotr(a, 2) ^ rotr(a, 13) ^ rotr(a, 22);
      const uint32_t mj = (a & bb) ^ (a & c) ^ (bb & c);
      const uint32_t t2 = S0 + mj;
      h = g;
      g = f;
      f = e;
      e = d + t1;
      d = c;
      c = bb;
      bb = a;
      a = t1 + t2;
    }
    h_[0] += a; h_[1] += bb; h_[2] += c; h_[3] += d;
    h_[4] += e; h_[5] += f; h_[6] += g; h_[7] += h;
  }
  uint32_t h_[8];
  uint64_t len_;
  uint8_t buf_[64];
  std::size_t fill_;
};

// HMAC-SHA256 with a fixed key: the padded inner and outer key blocks once.
class HmacSha256 {
 public:
  static constexpr std::size_t kSize = 32;
  explicit HmacSha256(const std::string& key) {
    uint8_t k[64] = {0};
    if (key.size() > 64) {
      const Sha256::Digest d = Sha256::of(key.data(), key.size());
      std::memcpy(k, d.data(), d.size());
    } else {
      std::memcpy(k, key.data(), key.size());
    }
    for (int i = 0; i < 64; ++i) {
      ipad_[i] = uint8_t(k[i] ^ 0x36);
      opad_[i] = uint8_t(k[i] ^ 0x5c);
    }
  }
  // HMAC over the concatenation of two pieces (channel, payload).
  Sha256::Digest mac(const void* a, std::size_t na, const void* b = nullptr, std::size_t nb = 0) const {
    Sha256 s;
    s.update(ipad_, 64);
    s.update(a, na);
    if (nb) s.update(b, nb);
    const Sha256::Digest inner = s.finish();
    s.update(opad_, 64);
    s.update(inner.data(), inner.size());
    return s.finish();
  }
  // The bench's message authentication: HMAC(key, channel || 0x00 || payload).
  // No allocation: the controller tags and verifies on its step path.
  Sha256::Digest message_tag(std::string_view channel, const void* payload, std::size_t n) const {
    static constexpr uint8_t kZero = 0;
    Sha256 s;
    s.update(ipad_, 64);
    s.update(channel.data(), channel.size());
    s.update(&kZero, 1);
    s.update(payload, n);
    const Sha256::Digest inner = s.finish();
    s.update(opad_, 64);
    s.update(inner.data(), inner.size());
    return s.finish();
  }
  // data = payload || tag: whether the tag verifies (constant time in the tag).
  bool verify(std::string_view channel, const void* data, std::size_t n) const {
    if (n < kSize) return false;
    const Sha256::Digest t = message_tag(channel, data, n - kSize);
    const uint8_t* got = static_cast<const uint8_t*>(data) + (n - kSize);
    uint8_t diff = 0;
    for (std::size_t i = 0; i < kSize; ++i) diff |= uint8_t(t[i] ^ got[i]);
    return diff == 0;
  }

 private:
  uint8_t ipad_[64], opad_[64];
};

}  // namespace sc_rt
