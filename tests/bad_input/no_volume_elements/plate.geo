// A surface and no volume: meshing gives no volume elements.
SetFactory("OpenCASCADE");
Rectangle(1) = {0, 0, 0, 1, 0.1};
Physical Surface("clamp") = {1};
