// LASzip item compressors, version 3 (the layered chunked compressor of LAS
// 1.4 point formats 6-8): the mirror of items_v3.cpp, on the same contexts,
// writing each attribute to its own layer as LASzip's writer does. A layer
// is stored only if some point of the chunk changed it (XY and Z always), so
// every value is still coded into every layer: whether it will be stored is
// known only at the chunk's end.
#include <cstring>

#include "laz/items.h"
#include "laz/items_v3_state.h"
#include "laz/tables.h"

namespace relief::laz {

std::uint32_t Point14V3::write(const std::uint8_t* item) {
  Fields cur;
  cur.load(item);
  Context* ctx = contexts_[current_].get();
  Fields* last = &ctx->last;

  // Context from the last point of the current channel, as the reader sees it.
  std::uint32_t lpr = last->return_number == 1 ? 1 : 0;
  lpr += last->return_number >= last->number_of_returns ? 2 : 0;
  lpr += last->gps_time_change ? 4 : 0;

  // Changes are against the last point of the point's own channel when that
  // channel has been seen in this chunk, else against the current one's
  // (which a new channel starts from).
  const std::uint32_t channel = cur.scanner_channel;
  const bool channel_change = channel != current_;
  if (channel_change && contexts_[channel] && !contexts_[channel]->unused) last = &contexts_[channel]->last;

  const bool point_source_change = cur.point_source != last->point_source;
  // Bits, not doubles: LASzip compares the doubles, so it would take -0.0
  // for 0.0 (and lose the sign); a NaN always counts as changed there, never
  // here when the bits repeat. Both are decodable either way.
  const bool gps_time_change = cur.gps_time != last->gps_time;
  const bool scan_angle_change = cur.scan_angle != last->scan_angle;
  const std::uint32_t last_n = last->number_of_returns;
  const std::uint32_t last_r = last->return_number;
  const std::uint32_t n = cur.number_of_returns;
  const std::uint32_t r = cur.return_number;

  std::uint32_t changed = (static_cast<std::uint32_t>(channel_change) << 6) |
                          (static_cast<std::uint32_t>(point_source_change) << 5) |
                          (static_cast<std::uint32_t>(gps_time_change) << 4) |
                          (static_cast<std::uint32_t>(scan_angle_change) << 3) |
                          (static_cast<std::uint32_t>(n != last_n) << 2);
  if (r != last_r) {
    if (r == (last_r + 1) % 16) {
      changed |= 1;
    } else if (r == (last_r + 15) % 16) {
      changed |= 2;
    } else {
      changed |= 3;
    }
  }
  ArithmeticEncoder& xy = out_layers_[kXY].enc;
  xy.encode_symbol(ctx->changed_values[lpr], changed);

  if (channel_change) {
    // The new channel as a step of 1-3 from the current one, modulo 4.
    xy.encode_symbol(ctx->scanner_channel, (channel + kScannerChannels - current_ - 1) % kScannerChannels);
    if (!contexts_[channel] || contexts_[channel]->unused) {
      const Fields from = ctx->last;
      init_context(channel, from);
      last = &contexts_[channel]->last;
    }
    current_ = channel;
    ctx = contexts_[current_].get();
  }

  if (changed & (1 << 2)) xy.encode_symbol(model_for(ctx->number_of_returns[last_n], 16), n);
  if ((changed & 3) == 3) {
    if (gps_time_change) {
      xy.encode_symbol(model_for(ctx->return_number[last_r], 16), r);
    } else {
      // r = last_r + 2 + symbol, modulo 16 (steps of +-1 have their own codes).
      xy.encode_symbol(ctx->return_number_gps_same, (r + 16 - last_r - 2) % 16);
    }
  }

  const auto [m, l, cpr] = return_contexts(n, r);
  const std::uint32_t gps_bit = gps_time_change ? 1 : 0;

  const std::size_t mi = (m << 1) | gps_bit;
  std::int32_t diff = wrap_sub(cur.x, last->x);
  ctx->ic_dx.compress(xy, ctx->last_x_diff[mi].get(), diff, n == 1);
  ctx->last_x_diff[mi].add(diff);
  std::uint32_t k_bits = ctx->ic_dx.k();
  diff = wrap_sub(cur.y, last->y);
  ctx->ic_dy.compress(xy, ctx->last_y_diff[mi].get(), diff, (n == 1) + (k_bits < 20 ? zero_bit0(k_bits) : 20));
  ctx->last_y_diff[mi].add(diff);

  k_bits = (ctx->ic_dx.k() + ctx->ic_dy.k()) / 2;
  ctx->ic_z.compress(out_layers_[kZ].enc, ctx->last_z[l], cur.z, (n == 1) + (k_bits < 18 ? zero_bit0(k_bits) : 18));
  ctx->last_z[l] = cur.z;

  OutLayer& cls = out_layers_[kClassification];
  cls.changed |= cur.classification != last->classification;
  const std::uint32_t ccc = ((last->classification & 0x1F) << 1) + (cpr == 3 ? 1 : 0);
  cls.enc.encode_symbol(model_for(ctx->classification[ccc], 256), cur.classification);

  OutLayer& flags = out_layers_[kFlags];
  const std::uint32_t last_flags = (last->edge << 5) | (last->scan_direction << 4) | last->classification_flags;
  const std::uint32_t cur_flags = (cur.edge << 5) | (cur.scan_direction << 4) | cur.classification_flags;
  flags.changed |= cur_flags != last_flags;
  flags.enc.encode_symbol(model_for(ctx->flags[last_flags], 64), cur_flags);

  OutLayer& intensity = out_layers_[kIntensity];
  intensity.changed |= cur.intensity != last->intensity;
  const std::size_t ii = (cpr << 1) | gps_bit;
  ctx->ic_intensity.compress(intensity.enc, ctx->last_intensity[ii], cur.intensity, cpr);
  ctx->last_intensity[ii] = cur.intensity;

  if (scan_angle_change) {
    OutLayer& angle = out_layers_[kScanAngle];
    angle.changed = true;
    ctx->ic_scan_angle.compress(angle.enc, last->scan_angle, cur.scan_angle, gps_bit);
  }

  OutLayer& user = out_layers_[kUserData];
  user.changed |= cur.user_data != last->user_data;
  user.enc.encode_symbol(model_for(ctx->user_data[last->user_data / 4], 256), cur.user_data);

  if (point_source_change) {
    OutLayer& source = out_layers_[kPointSource];
    source.changed = true;
    ctx->ic_point_source.compress(source.enc, last->point_source, cur.point_source);
  }
  if (gps_time_change) {
    OutLayer& gps = out_layers_[kGpsTime];
    gps.changed = true;
    gps_encode(gps.enc, ctx->gps, cur.gps_time, kGpsCodesV3);
  }

  *last = cur;
  last->gps_time_change = gps_time_change;
  return current_;
}

void Rgb14V3::write(const std::uint8_t* item, std::uint32_t context) {
  std::uint16_t* last = switch_context(context);
  Context& ctx = *contexts_[current_];
  const std::uint16_t c[3] = {get_u16(item), get_u16(item + 2), get_u16(item + 4)};
  if (encode_rgb(out_layers_[0].enc, ctx.rgb, last, c) != 0) out_layers_[0].changed = true;
  for (int i = 0; i < 3; ++i) last[i] = c[i];
  if (!nir_) return;
  const std::uint16_t nir = get_u16(item + 6);
  const int lo_diff = (nir & 0xFF) - (last[3] & 0xFF);
  const int hi_diff = (nir >> 8) - (last[3] >> 8);
  const std::uint32_t sym = (lo_diff != 0 ? 1u : 0u) | (hi_diff != 0 ? 2u : 0u);
  ArithmeticEncoder& enc = out_layers_[1].enc;
  enc.encode_symbol(ctx.nir_used, sym);
  if (sym & 1) enc.encode_symbol(ctx.nir_diff[0], fold8(lo_diff));
  if (sym & 2) enc.encode_symbol(ctx.nir_diff[1], fold8(hi_diff));
  if (sym != 0) out_layers_[1].changed = true;
  last[3] = nir;
}

void Byte14V3::write(const std::uint8_t* item, std::uint32_t context) {
  std::uint8_t* last = switch_context(context);
  Context& ctx = *contexts_[current_];
  for (std::size_t i = 0; i < n_; ++i) {
    out_layers_[i].enc.encode_symbol(ctx.models[i], fold8(static_cast<int>(item[i]) - static_cast<int>(last[i])));
    if (item[i] != last[i]) {
      out_layers_[i].changed = true;
      last[i] = item[i];
    }
  }
}

}  // namespace relief::laz
