// Slender cantilever: length L along x, height h along y, width b along z.
// Physical groups: volume "beam"; surfaces "clamp" (x = 0) and "tip" (x = L).
SetFactory("OpenCASCADE");
L = 1.0;
h = 0.05;
b = 0.1;
Box(1) = {0, 0, 0, L, h, b};
Physical Volume("beam") = {1};
eps = 1e-6;
Physical Surface("clamp") = Surface In BoundingBox{-eps, -eps, -eps, eps, h + eps, b + eps};
Physical Surface("tip") = Surface In BoundingBox{L - eps, -eps, -eps, L + eps, h + eps, b + eps};
