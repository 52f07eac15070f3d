// The benchmark link of scripts/bench/acf_link.sh: a straight steel link of length L along x with
// a square b x b cross-section centred on the x-axis (0.6 m x 40 x 40 mm).
// Physical groups: volume "link"; surfaces "end_a" (x = 0) and "end_b" (x = L).
SetFactory("OpenCASCADE");
L = 0.6; b = 0.04;
Box(1) = {0, -b/2, -b/2, L, b, b};
eps = 1e-6;
Physical Volume("link") = {1};
Physical Surface("end_a") = Surface In BoundingBox{-eps, -b, -b, eps, b, b};
Physical Surface("end_b") = Surface In BoundingBox{L - eps, -b, -b, L + eps, b, b};
