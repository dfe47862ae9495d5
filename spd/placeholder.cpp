int rayfarm_spd_placeholder_tu = 0;
