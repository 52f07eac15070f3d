// The ACF body's elastic-displacement frame and its reverse derivative (docs/theory.md 8.4).
#include "flexopt/dynamics/interface_frame.hpp"

#include "flexopt/core/error.hpp"

#include <cmath>
#include <sstream>

namespace flexopt::dynamics {

using bodies::Mat3;
using bodies::Vec3;

namespace {

/// The chord's quantities: a = A(p0) d0^, b = l / |l|, v = a x b, c = a . b and Q(a, b).
struct Chord {
  Vec3 d_hat, l, a, b, v;
  double length = 0, c = 1;
  Mat3 Q = Mat3::Identity();
};

/// The message's start: the body and the time (built only when the frame is refused).
std::string where(const std::string &body, double t) {
  std::ostringstream s;
  s << "body '" << body << "': elastic_displacement's chord frame at t = " << t << " s";
  return s.str();
}

Chord chord(const FrameNodes &n, const Mat3 &A0, const std::string &body, double t) {
  Chord ch;
  ch.d_hat = (n.c1 - n.c0).normalized();
  ch.l = n.r1 - n.r0;
  ch.length = ch.l.norm();
  ch.a = A0 * ch.d_hat;
  if (!(ch.length > 0) || !std::isfinite(ch.length))
    throw Error(where(body, t) + ": the chord frame's two interfaces meet (the axis is undefined)",
                true);
  ch.b = ch.l / ch.length;
  ch.v = ch.a.cross(ch.b);
  ch.c = ch.a.dot(ch.b);
  if (!(ch.c > 0)) {
    std::ostringstream msg;
    msg << where(body, t) << ": the chord has turned by "
        << std::acos(std::max(-1.0, std::min(1.0, ch.c)))
        << " rad from the first interface's axis; the chord frame (docs/theory.md section 8.4) is "
           "defined below pi/2 only";
    throw Error(msg.str(), true);
  }
  const Mat3 V = bodies::skew(ch.v);
  ch.Q = Mat3::Identity() + V + V * V / (1 + ch.c);
  return ch;
}

} // namespace

InterfaceFrame interface_frame(const FrameNodes &n, const std::string &body, double t) {
  InterfaceFrame f;
  f.r = n.r0;
  f.c = n.c0;
  const Mat3 A0 = bodies::rotation(n.p0);
  f.A = n.condition == reduce::FrameCondition::Chord ? Mat3(chord(n, A0, body, t).Q * A0) : A0;
  return f;
}

FrameCotangent elastic_cotangent(const FrameNodes &n, const Vec3 &x, const Vec3 &w,
                                 const std::string &body, double t) {
  FrameCotangent ct;
  const Mat3 A0 = bodies::rotation(n.p0);
  const Vec3 z = x - n.r0;
  if (n.condition != reduce::FrameCondition::Chord) {
    ct.x = A0 * w;
    ct.r0 = -ct.x;
    ct.p0 = bodies::rotate_jacobian(n.p0, w).transpose() * z;
    return ct;
  }
  const Chord ch = chord(n, A0, body, t);
  ct.x = ch.Q * (A0 * w);
  // w . e = z^T Q A(p0) w: through A(p0) directly, and through Q (Qbar = z (A(p0) w)^T).
  ct.p0 = bodies::rotate_jacobian(n.p0, w).transpose() * (ch.Q.transpose() * z);
  const Mat3 Qb = z * (A0 * w).transpose();
  const double s = 1 / (1 + ch.c);
  const Vec3 vb = Vec3(Qb(2, 1) - Qb(1, 2), Qb(0, 2) - Qb(2, 0), Qb(1, 0) - Qb(0, 1)) +
                  s * ((Qb + Qb.transpose()) * ch.v - 2 * Qb.trace() * ch.v);
  const double cb = -s * s * (ch.v.dot(Qb * ch.v) - ch.v.squaredNorm() * Qb.trace());
  const Vec3 ab = ch.b.cross(vb) + cb * ch.b;
  const Vec3 bb = vb.cross(ch.a) + cb * ch.a;
  const Vec3 lb = (bb - ch.b * ch.b.dot(bb)) / ch.length;
  ct.p0 += bodies::rotate_jacobian(n.p0, ch.d_hat).transpose() * ab;
  ct.r1 = lb;
  ct.r0 = -ct.x - lb;
  return ct;
}

} // namespace flexopt::dynamics
