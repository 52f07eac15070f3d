// A cantilever of length 1 m (x), 0.05 m deep (y), 0.1 m wide (z) in two parts: "root"
// (x < 0.2, clamped at x = 0) and "design" (the rest, loaded at x = 1).
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.2, 0.05, 0.1};
Box(2) = {0.2, 0, 0, 0.8, 0.05, 0.1};
v() = BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; };
eps = 1e-6;
Physical Volume("root") = Volume In BoundingBox{-eps, -eps, -eps, 0.2 + eps, 0.05 + eps, 0.1 + eps};
Physical Volume("design") = Volume In BoundingBox{0.2 - eps, -eps, -eps, 1 + eps, 0.05 + eps, 0.1 + eps};
Physical Surface("clamp") = Surface In BoundingBox{-eps, -eps, -eps, eps, 0.05 + eps, 0.1 + eps};
Physical Surface("tip") = Surface In BoundingBox{1 - eps, -eps, -eps, 1 + eps, 0.05 + eps, 0.1 + eps};
