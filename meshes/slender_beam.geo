// Slender cantilever with a square section, for the rotating-beam (Southwell) test: length L along
// x, b x b cross-section centred on the x axis (L / b = 25).
// Physical groups: volume "beam"; surfaces "root" (x = 0) and "tip" (x = L).
SetFactory("OpenCASCADE");
L = 1.0;
b = 0.04;
Box(1) = {0, -b/2, -b/2, L, b, b};
eps = 1e-6;
Physical Volume("beam") = {1};
Physical Surface("root") = Surface In BoundingBox{-eps, -b, -b, eps, b, b};
Physical Surface("tip") = Surface In BoundingBox{L - eps, -b, -b, L + eps, b, b};
