// The Kane / Simo & Vu-Quoc spin-up beam as a 3D solid: L = 10 m along x with the square
// section b x b that has the beam's EA/EI ratio (I/A = b^2/12 = EI/EA = 5e-4 m^2, b = 0.07746 m).
// Physical groups: volume "beam"; surfaces "root" (x = 0) and "tip" (x = L).
SetFactory("OpenCASCADE");
L = 10.0; b = Sqrt(12 * 5e-4);
Box(1) = {0, -b/2, -b/2, L, b, b};
eps = 1e-6;
Physical Volume("beam") = {1};
Physical Surface("root") = Surface In BoundingBox{-eps, -b, -b, eps, b, b};
Physical Surface("tip") = Surface In BoundingBox{L - eps, -b, -b, L + eps, b, b};
