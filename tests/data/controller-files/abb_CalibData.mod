MODULE CalibData
    PERS tooldata Gripper:=[TRUE,[[0,1,330],[1,0,0,0]],[3,[0,0,30],[1,0,0,0],0,0,0]];
    PERS tooldata Gripper_closed:=[TRUE,[[0,10.8,330],[1,0,0,0]],[3,[0,0,30],[1,0,0,0],0,0,0]];
    TASK PERS wobjdata Sleeves:=[FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[992.91,-2164.96,1565],[0,0,1,0]]];
    TASK PERS wobjdata Mandrell:=[FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[2812.88,-226.05,592.36],[0.27444,0.27271,0.64992,0.65415]]];
    PERS tooldata Gripper_Sleeve:=[TRUE,[[0,6.4,1700],[1,-0.00161,0,0]],[25,[0,0,800],[1,0,0,0],0,0,0]];
    PERS tooldata Gripper_Sleeve_Horizontal:=[TRUE,[[0,-21,1700],[0.99998,0.00625,0,0]],[25,[0,0,800],[1,0,0,0],0,0,0]];
    PERS tooldata Gripper_closed_V:=[TRUE,[[43,-20.8,270],[1,0,0,0]],[3,[0,0,30],[1,0,0,0],0,0,0]];
    TASK PERS wobjdata Laser:=[FALSE,TRUE,"",[[0,0,0],[1,0,0,0]],[[1457,-1157,-235],[1,0,0,0]]];
ENDMODULE