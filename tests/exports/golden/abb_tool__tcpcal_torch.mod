MODULE tcpcal_torch
  ! tcpcal tool data
  ! tool torch (tool 3) version 4
  ! calibrated 2026-11-24 05:00 UTC by alice (xyz_npoint)
  ! https://tcpcal.plant.example/ui/tools/t3
  ! from https://tcpcal.plant.example
  PERS tooldata torch:=[TRUE,[[1.5,-2.25,150.0],[0.707106781,0.0,-0.707106781,0.0]],[2.5,[0.0,0.0,80.0],[1,0,0,0],0,0,0]];
ENDMODULE
