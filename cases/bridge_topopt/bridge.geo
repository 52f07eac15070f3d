// A bridge over a river: a 4 x 1 x 0.5 m block between two abutments (x = 0 and x = 4),
// with a solid deck (the top 0.1 m) and a half-cylinder channel (radius 0.6 m) cut out of
// its underside. Unstructured tetrahedra follow the curved channel wall.
// Physical groups: volumes "design" (below the deck) and "deck"; surfaces "abutment_left",
// "abutment_right" (the end faces) and "road" (the top of the deck).
SetFactory("OpenCASCADE");
L = 4.0; H = 1.0; W = 0.5; t = 0.1; R = 0.6;
Box(1) = {0, 0, 0, L, H - t, W};
Box(2) = {0, H - t, 0, L, t, W};
Cylinder(3) = {L / 2, 0, 0, 0, 0, W, R};
BooleanDifference(4) = {Volume{1}; Delete;}{Volume{3}; Delete;};
BooleanFragments{Volume{4, 2}; Delete;}{}
eps = 1e-6;
Physical Volume("design") = Volume In BoundingBox{-eps, -eps, -eps, L + eps, H - t + eps, W + eps};
Physical Volume("deck") = Volume In BoundingBox{-eps, H - t - eps, -eps, L + eps, H + eps, W + eps};
Physical Surface("abutment_left") = Surface In BoundingBox{-eps, -eps, -eps, eps, H + eps, W + eps};
Physical Surface("abutment_right") = Surface In BoundingBox{L - eps, -eps, -eps, L + eps, H + eps, W + eps};
Physical Surface("road") = Surface In BoundingBox{-eps, H - eps, -eps, L + eps, H + eps, W + eps};
