int rayfarm_placeholder_tu = 0;
