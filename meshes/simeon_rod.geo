// The elastic connecting rod of Simeon's flexible slider-crank: 0.30 m along x, 8 x 8 mm
// section. Physical groups: volume "rod"; surfaces "end_a" (x = 0) and "end_b" (x = L).
SetFactory("OpenCASCADE");
L = 0.30; b = 0.008;
Box(1) = {0, -b/2, -b/2, L, b, b};
eps = 1e-6;
Physical Volume("rod") = {1};
Physical Surface("end_a") = Surface In BoundingBox{-eps, -b, -b, eps, b, b};
Physical Surface("end_b") = Surface In BoundingBox{L - eps, -b, -b, L + eps, b, b};
