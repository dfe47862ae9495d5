int rayfarm_farm_placeholder_tu = 0;
