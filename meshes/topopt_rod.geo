// The connecting rod of cases/slider_crank_topopt: a plate link of L = 0.30 m between pin centres
// (a file that sets L and includes this one makes the same link at another length:
// topopt_crank.geo, fourbar_rocker.geo),
// 40 mm deep (y) and 10 mm thick (z), with rounded ends (bosses of radius 20 mm) and pin holes
// of radius 6 mm. The part between x = 30 mm and x = 270 mm is the design region; the bosses
// stay solid, so the pin surfaces (the joints' rigid interfaces) never touch it.
// Physical groups: volumes "design" and "boss" (both ends); surfaces "pin_a" (the hole at
// x = 0, centroid at the origin) and "pin_b" (the hole at x = L).
SetFactory("OpenCASCADE");
If (!Exists(L))
  L = 0.30;
EndIf
H = 0.04; T = 0.01; R = H / 2; r = 0.006; d = 0.03;
Box(1) = {0, -H / 2, -T / 2, L, H, T};
Cylinder(2) = {0, 0, -T / 2, 0, 0, T, R};
Cylinder(3) = {L, 0, -T / 2, 0, 0, T, R};
Cylinder(4) = {0, 0, -T / 2, 0, 0, T, r};
Cylinder(5) = {L, 0, -T / 2, 0, 0, T, r};
BooleanUnion(6) = {Volume{1}; Delete;}{Volume{2, 3}; Delete;};
BooleanDifference(7) = {Volume{6}; Delete;}{Volume{4, 5}; Delete;};
// Cut at x = d and x = L - d: the design region between, the bosses outside (conforming).
Box(8) = {d, -H, -T, L - 2 * d, 2 * H, 2 * T};
middle[] = BooleanIntersection{Volume{7};}{Volume{8};};
ends[] = BooleanDifference{Volume{7}; Delete;}{Volume{8}; Delete;};
BooleanFragments{Volume{middle[], ends[]}; Delete;}{}
eps = 1e-4;
Physical Volume("design") = Volume In BoundingBox{d - eps, -H / 2 - eps, -T / 2 - eps, L - d + eps, H / 2 + eps, T / 2 + eps};
Physical Volume("boss") = {Volume In BoundingBox{-R - eps, -R - eps, -T / 2 - eps, d + eps, R + eps, T / 2 + eps},
                           Volume In BoundingBox{L - d - eps, -R - eps, -T / 2 - eps, L + R + eps, R + eps, T / 2 + eps}};
Physical Surface("pin_a") = Surface In BoundingBox{-r - eps, -r - eps, -T / 2 - eps, r + eps, r + eps, T / 2 + eps};
Physical Surface("pin_b") = Surface In BoundingBox{L - r - eps, -r - eps, -T / 2 - eps, L + r + eps, r + eps, T / 2 + eps};
