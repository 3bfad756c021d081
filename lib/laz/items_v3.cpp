// LASzip item decompressors, version 3 (the layered chunked compressor of
// LAS 1.4 point formats 6-8); the compressors are in items_v3_write.cpp.
#include <cstring>

#include "laz/items.h"
#include "laz/items_v3_state.h"
#include "laz/tables.h"

namespace relief::laz {

bool start_layers(std::span<Layer> layers, std::span<const std::uint8_t> data) {
  std::size_t at = 0;
  for (Layer& layer : layers) {
    // Every decoder is started, even on no bytes, so that none is ever used
    // uninitialised; an empty layer reads as zeros and is flagged as overrun
    // if anything decodes from it.
    if (!layer.dec.init(data.subspan(at, layer.size))) return false;
    layer.changed = layer.size != 0;
    at += layer.size;
  }
  return true;
}

Point14V3::Point14V3() {
  // LASzip stores these two layers in every chunk, changed or not.
  out_layers_[kXY].always = true;
  out_layers_[kZ].always = true;
}
Point14V3::~Point14V3() = default;

void Point14V3::init_context(std::uint32_t c, const Fields& from) {
  if (!contexts_[c]) contexts_[c] = std::make_unique<Context>();
  Context& ctx = *contexts_[c];
  for (auto& m : ctx.changed_values) m.init();
  ctx.scanner_channel.init();
  init_existing(ctx.number_of_returns);
  init_existing(ctx.return_number);
  ctx.return_number_gps_same.init();
  ctx.ic_dx.init();
  ctx.ic_dy.init();
  for (int i = 0; i < 12; ++i) {
    ctx.last_x_diff[i].init();
    ctx.last_y_diff[i].init();
  }
  ctx.ic_z.init();
  ctx.last_z.fill(from.z);
  init_existing(ctx.classification);
  init_existing(ctx.flags);
  init_existing(ctx.user_data);
  ctx.ic_intensity.init();
  ctx.last_intensity.fill(from.intensity);
  ctx.ic_scan_angle.init();
  ctx.ic_point_source.init();
  ctx.gps.init(from.gps_time);
  ctx.last = from;
  ctx.last.gps_time_change = false;
  ctx.unused = false;
}

std::uint32_t Point14V3::init(const std::uint8_t* item) {
  for (auto& c : contexts_) {
    if (c) c->unused = true;
  }
  Fields f;
  f.load(item);
  current_ = f.scanner_channel;
  init_context(current_, f);
  return current_;
}

void Point14V3::read_gps_time(Context& ctx) {
  GpsTimeState& s = ctx.gps;
  ArithmeticDecoder& dec = layers_[kGpsTime].dec;
  for (int hop = 0; hop <= kMaxSequenceSwitches; ++hop) {
    if (s.diff[s.last] == 0) {
      const std::uint32_t multi = dec.decode_symbol(s.zero_diff);
      if (multi == 0) {
        s.diff[s.last] = s.ic.decompress(dec, 0, 0);
        s.time[s.last] += static_cast<std::uint64_t>(static_cast<std::int64_t>(s.diff[s.last]));
        s.extreme[s.last] = 0;
      } else if (multi == 1) {
        gps_decode_full(dec, s);
      } else {
        s.last = (s.last + multi - 1) & 3;
        continue;
      }
    } else {
      const std::uint32_t multi = dec.decode_symbol(s.multi);
      if (multi == 1) {
        s.time[s.last] +=
            static_cast<std::uint64_t>(static_cast<std::int64_t>(s.ic.decompress(dec, s.diff[s.last], 1)));
        s.extreme[s.last] = 0;
      } else if (multi < kGpsMultiCodeFullV3) {
        gps_decode_multiple(dec, s, multi);
      } else if (multi == kGpsMultiCodeFullV3) {
        gps_decode_full(dec, s);
      } else {
        s.last = (s.last + multi - kGpsMultiCodeFullV3) & 3;
        continue;
      }
    }
    break;
  }
}

std::uint32_t Point14V3::read(std::uint8_t* item) {
  ArithmeticDecoder& xy = layers_[kXY].dec;
  Context* ctx = contexts_[current_].get();
  Fields* last = &ctx->last;

  // Context from the last point: first / last return and whether its GPS time changed.
  std::uint32_t lpr = last->return_number == 1 ? 1 : 0;
  lpr += last->return_number >= last->number_of_returns ? 2 : 0;
  lpr += last->gps_time_change ? 4 : 0;
  const std::uint32_t changed = xy.decode_symbol(ctx->changed_values[lpr]);

  if (changed & (1 << 6)) {
    const std::uint32_t diff = xy.decode_symbol(ctx->scanner_channel);
    const std::uint32_t channel = (current_ + diff + 1) % kScannerChannels;
    if (!contexts_[channel] || contexts_[channel]->unused) {
      const Fields from = *last;
      init_context(channel, from);
    }
    current_ = channel;
    ctx = contexts_[current_].get();
    last = &ctx->last;
    last->scanner_channel = channel;
  }

  const bool point_source_change = (changed & (1 << 5)) != 0;
  const bool gps_time_change = (changed & (1 << 4)) != 0;
  const bool scan_angle_change = (changed & (1 << 3)) != 0;

  const std::uint32_t last_n = last->number_of_returns;
  const std::uint32_t last_r = last->return_number;
  std::uint32_t n = last_n;
  if (changed & (1 << 2)) {
    SymbolModel& model = model_for(ctx->number_of_returns[last_n], 16);
    n = xy.decode_symbol(model);
    last->number_of_returns = n;
  }
  std::uint32_t r = last_r;
  switch (changed & 3) {
    case 0:
      break;
    case 1:
      r = (last_r + 1) % 16;
      break;
    case 2:
      r = (last_r + 15) % 16;
      break;
    default:
      if (gps_time_change) {
        SymbolModel& model = model_for(ctx->return_number[last_r], 16);
        r = xy.decode_symbol(model);
      } else {
        r = (last_r + xy.decode_symbol(ctx->return_number_gps_same) + 2) % 16;
      }
      break;
  }
  last->return_number = r;

  const auto [m, l, cpr] = return_contexts(n, r);
  const std::uint32_t gps_bit = gps_time_change ? 1 : 0;

  const std::size_t mi = (m << 1) | gps_bit;
  std::int32_t diff = ctx->ic_dx.decompress(xy, ctx->last_x_diff[mi].get(), n == 1);
  last->x = wrap_add(last->x, diff);
  ctx->last_x_diff[mi].add(diff);
  std::uint32_t k_bits = ctx->ic_dx.k();
  diff = ctx->ic_dy.decompress(xy, ctx->last_y_diff[mi].get(), (n == 1) + (k_bits < 20 ? zero_bit0(k_bits) : 20));
  last->y = wrap_add(last->y, diff);
  ctx->last_y_diff[mi].add(diff);

  if (layers_[kZ].changed) {
    k_bits = (ctx->ic_dx.k() + ctx->ic_dy.k()) / 2;
    last->z = ctx->ic_z.decompress(layers_[kZ].dec, ctx->last_z[l],
                                   (n == 1) + (k_bits < 18 ? zero_bit0(k_bits) : 18));
    ctx->last_z[l] = last->z;
  }
  if (layers_[kClassification].changed) {
    const std::uint32_t ccc = ((last->classification & 0x1F) << 1) + (cpr == 3 ? 1 : 0);
    SymbolModel& model = model_for(ctx->classification[ccc], 256);
    last->classification = layers_[kClassification].dec.decode_symbol(model);
  }
  if (layers_[kFlags].changed) {
    const std::uint32_t last_flags = (last->edge << 5) | (last->scan_direction << 4) | last->classification_flags;
    SymbolModel& model = model_for(ctx->flags[last_flags], 64);
    const std::uint32_t flags = layers_[kFlags].dec.decode_symbol(model);
    last->edge = (flags >> 5) & 1;
    last->scan_direction = (flags >> 4) & 1;
    last->classification_flags = flags & 0x0F;
  }
  if (layers_[kIntensity].changed) {
    const std::size_t ii = (cpr << 1) | gps_bit;
    const auto v = static_cast<std::uint16_t>(
        ctx->ic_intensity.decompress(layers_[kIntensity].dec, ctx->last_intensity[ii], cpr));
    ctx->last_intensity[ii] = v;
    last->intensity = v;
  }
  if (layers_[kScanAngle].changed && scan_angle_change) {
    last->scan_angle = static_cast<std::int16_t>(
        ctx->ic_scan_angle.decompress(layers_[kScanAngle].dec, last->scan_angle, gps_bit));
  }
  if (layers_[kUserData].changed) {
    SymbolModel& model = model_for(ctx->user_data[last->user_data / 4], 256);
    last->user_data = layers_[kUserData].dec.decode_symbol(model);
  }
  if (layers_[kPointSource].changed && point_source_change) {
    last->point_source = static_cast<std::uint16_t>(
        ctx->ic_point_source.decompress(layers_[kPointSource].dec, last->point_source));
  }
  if (layers_[kGpsTime].changed && gps_time_change) {
    read_gps_time(*ctx);
    last->gps_time = ctx->gps.time[ctx->gps.last];
  }
  last->store(item);
  last->gps_time_change = gps_time_change;
  return current_;
}

// ---------------------------------------------------------------- RGB14, RGBNIR14

void Rgb14V3::init_context(std::uint32_t c, const std::uint16_t* from) {
  if (!contexts_[c]) contexts_[c] = std::make_unique<Context>();
  Context& ctx = *contexts_[c];
  ctx.rgb.init();
  ctx.nir_used.init();
  ctx.nir_diff[0].init();
  ctx.nir_diff[1].init();
  std::memcpy(ctx.last.data(), from, sizeof(ctx.last));
  ctx.unused = false;
}

void Rgb14V3::init(const std::uint8_t* item, std::uint32_t context) {
  for (auto& c : contexts_) {
    if (c) c->unused = true;
  }
  std::uint16_t first[4] = {get_u16(item), get_u16(item + 2), get_u16(item + 4),
                            static_cast<std::uint16_t>(nir_ ? get_u16(item + 6) : 0)};
  current_ = context;
  init_context(current_, first);
}

Rgb14V3::Rgb14V3(bool nir) : nir_(nir), layers_(nir ? 2 : 1), out_layers_(nir ? 2 : 1) {}

std::uint16_t* Rgb14V3::switch_context(std::uint32_t context) {
  // As in LASzip, the values predicted from (and updated) stay those of the
  // previous channel when switching to a channel already seen in this chunk;
  // only a channel's first use copies them.
  std::uint16_t* last = contexts_[current_]->last.data();
  if (current_ != context) {
    current_ = context;
    if (!contexts_[current_] || contexts_[current_]->unused) {
      const std::array<std::uint16_t, 4> from = {last[0], last[1], last[2], last[3]};
      init_context(current_, from.data());
      last = contexts_[current_]->last.data();
    }
  }
  return last;
}

void Rgb14V3::read(std::uint8_t* item, std::uint32_t context) {
  std::uint16_t* last = switch_context(context);
  Context& ctx = *contexts_[current_];
  if (layers_[0].changed) {
    std::uint16_t out[3];
    decode_rgb(layers_[0].dec, ctx.rgb, last, out);
    for (int i = 0; i < 3; ++i) {
      put_u16(item + 2 * i, out[i]);
      last[i] = out[i];
    }
  } else {
    for (int i = 0; i < 3; ++i) put_u16(item + 2 * i, last[i]);
  }
  if (!nir_) return;
  if (layers_[1].changed) {
    ArithmeticDecoder& dec = layers_[1].dec;
    const std::uint32_t sym = dec.decode_symbol(ctx.nir_used);
    std::uint16_t v;
    if (sym & 1) {
      v = fold8(static_cast<int>(dec.decode_symbol(ctx.nir_diff[0])) + (last[3] & 0xFF));
    } else {
      v = last[3] & 0xFF;
    }
    if (sym & 2) {
      v |= static_cast<std::uint16_t>(fold8(static_cast<int>(dec.decode_symbol(ctx.nir_diff[1])) + (last[3] >> 8))
                                      << 8);
    } else {
      v |= last[3] & 0xFF00;
    }
    last[3] = v;
  }
  put_u16(item + 6, last[3]);
}

// ---------------------------------------------------------------- BYTE14

void Byte14V3::init_context(std::uint32_t c, const std::uint8_t* from) {
  if (!contexts_[c]) {
    contexts_[c] = std::make_unique<Context>();
    contexts_[c]->models.assign(n_, SymbolModel(256));
    contexts_[c]->last.resize(n_);
  }
  Context& ctx = *contexts_[c];
  for (auto& m : ctx.models) m.init();
  std::memcpy(ctx.last.data(), from, n_);
  ctx.unused = false;
}

void Byte14V3::init(const std::uint8_t* item, std::uint32_t context) {
  for (auto& c : contexts_) {
    if (c) c->unused = true;
  }
  current_ = context;
  init_context(current_, item);
}

std::uint8_t* Byte14V3::switch_context(std::uint32_t context) {
  // The same quirk as Rgb14V3::switch_context.
  std::uint8_t* last = contexts_[current_]->last.data();
  if (current_ != context) {
    current_ = context;
    if (!contexts_[current_] || contexts_[current_]->unused) {
      const std::vector<std::uint8_t> from(last, last + n_);
      init_context(current_, from.data());
      last = contexts_[current_]->last.data();
    }
  }
  return last;
}

void Byte14V3::read(std::uint8_t* item, std::uint32_t context) {
  std::uint8_t* last = switch_context(context);
  Context& ctx = *contexts_[current_];
  for (std::size_t i = 0; i < n_; ++i) {
    if (layers_[i].changed) {
      last[i] = fold8(static_cast<int>(last[i]) + static_cast<int>(layers_[i].dec.decode_symbol(ctx.models[i])));
    }
    item[i] = last[i];
  }
}

}  // namespace relief::laz
